//! `ebiv process`: velocity fields from an event recording, by sum of correlation or motion
//! compensation, multi-pass, validated, written to disk and drawn.

use super::process_config::{Duration, ListOfU32, ProcessConfig};
use super::process_run::{run_config, Settings};
use crate::input::InputArgs;
use clap::Args;
use std::path::PathBuf;

/// Measure velocity fields from an event recording (Willert & Klinner 2022), or by PIV from
/// image pairs (`--method piv --images A B`).
///
/// Every flag is also a key of the configuration file (`ebiv init` writes one with all of
/// them, commented); flags override the file. Durations take units (10ms, 250us, 1.5s),
/// lengths are pixels, velocities px/ms (m/s with --mm-per-px). A field's time t0 is the
/// centre of its time slab.
#[derive(Debug, Args)]
pub struct ProcessArgs {
    /// The recording (any format `ebiv info` reads); not needed with --images.
    pub file: Option<PathBuf>,
    /// Settings file (TOML, see `ebiv init`); flags override its keys.
    #[arg(long, value_name = "TOML")]
    pub config: Option<PathBuf>,
    /// Estimator: `corrsum` (sum of correlation, fast), `motion` (motion compensation),
    /// `piv` (cross-correlation PIV of frames rebuilt from the events, or of `--images`) or
    /// `pulsed` (PIV of one frame per light pulse, pulse timing detected).
    #[arg(long)]
    pub method: Option<String>,
    /// piv: image files or patterns (`frames/*.png`) instead of a recording; pairs (1,2),
    /// (3,4), …; u and v are then displacements in px (velocities with --dt).
    #[arg(long, num_args = 1.., value_name = "IMAGE")]
    pub images: Option<Vec<String>>,
    /// piv images: pair the images as a sequence (1,2), (2,3), …
    #[arg(long)]
    pub sequence: bool,
    /// piv images: sum the correlation planes of all pairs into one field (ensemble PIV).
    #[arg(long)]
    pub ensemble: bool,
    /// piv images: time between the two frames of a pair; outputs velocities in px/ms.
    #[arg(long, value_parser = parse_duration, value_name = "DUR")]
    pub dt: Option<Duration>,
    /// piv: overlap of neighbouring windows, 0 ≤ overlap < 1 (default 0.5), when --step is
    /// not given.
    #[arg(long)]
    pub overlap: Option<f64>,
    /// piv: correlation, circular (default) or linear (zero-padded).
    #[arg(long)]
    pub correlation: Option<String>,
    /// piv: window deformation, symmetric (default) or second.
    #[arg(long)]
    pub deformation: Option<String>,
    /// piv: image interpolation for the deformation: quintic (default), cubic or linear.
    #[arg(long)]
    pub interpolation: Option<String>,
    /// piv: repetitions of the last pass at most (default 2; stops when the field changes by
    /// less than 0.01 px).
    #[arg(long)]
    pub iterations: Option<u32>,
    /// piv of events: exposure of one rebuilt frame (default 1.5ms).
    #[arg(long, value_parser = parse_duration, value_name = "DUR")]
    pub exposure: Option<Duration>,
    /// piv of events: time Δt between consecutive frames (default 2.5ms).
    #[arg(long, value_parser = parse_duration, value_name = "DUR")]
    pub frame_step: Option<Duration>,
    /// piv of events: frame kind, count (default), binary or time-surface.
    #[arg(long)]
    pub frame_kind: Option<String>,
    /// piv of events: spread each event over a Gaussian of this σ in px (default 0).
    #[arg(long, value_name = "PX")]
    pub splat: Option<f64>,
    /// piv of events: frame pairs per field whose correlation planes are summed (default
    /// 1; 3 for the paper's four-frame sequences).
    #[arg(long)]
    pub pairs: Option<u32>,
    /// pulsed: nominal pulse frequency in Hz (default: found from the events or triggers).
    #[arg(long, value_name = "HZ")]
    pub pulse_hz: Option<f64>,
    /// Mask image of the sensor's size (PNG, TIFF, BMP): non-zero pixels are left out;
    /// windows centred on them are flagged `masked`.
    #[arg(long, value_name = "IMAGE")]
    pub mask: Option<PathBuf>,
    /// Window size in px, one per pass, largest first (e.g. `40` or `64,40`). Default:
    /// 64,40 (piv: 64,32,16).
    #[arg(long, alias = "passes", value_parser = ListOfU32::parse, value_name = "PX[,PX..]")]
    pub window: Option<ListOfU32>,
    /// Grid step in px, one per pass (default: half of each window).
    #[arg(long, value_parser = ListOfU32::parse, value_name = "PX[,PX..]")]
    pub step: Option<ListOfU32>,
    /// Time slab T of one field (default 10ms).
    #[arg(long, value_parser = parse_duration, value_name = "DUR")]
    pub slab: Option<Duration>,
    /// corrsum: delay τ between the two sub-volumes (default 3ms).
    #[arg(long, value_parser = parse_duration, value_name = "DUR")]
    pub tau: Option<Duration>,
    /// corrsum: time slices N_T per sub-volume (default 20).
    #[arg(long)]
    pub slices: Option<u32>,
    /// Field centre times START:END:STEP (END inclusive), from the first event, e.g.
    /// `60ms:60ms:1ms` for one field at 60 ms. START or END may be left out (`::5ms`).
    /// Default: every field that fits in the recording, one per slab.
    #[arg(long, value_name = "START:END:STEP")]
    pub time: Option<String>,
    /// Read --time as camera time stamps rather than from the first event.
    #[arg(long)]
    pub absolute_time: bool,
    /// Events used: pos, neg or both (default pos, as in the paper).
    #[arg(long)]
    pub polarity: Option<String>,
    /// Region the windows must lie in: x,y,width,height (px).
    #[arg(long, value_name = "X,Y,W,H")]
    pub roi: Option<String>,
    /// Output file: .nc (NetCDF), .csv, .npz, .dat (Tecplot) or .vtk (default flow.nc).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Folder for figures: vector map per field over its event image, histograms of u and
    /// v, and an animated GIF of the series.
    #[arg(long, value_name = "DIR")]
    pub png: Option<PathBuf>,
    /// Sub-pixel peak fit: gauss3, parabolic or gauss2d (motion: only where its grid search
    /// runs; the Newton search finds the continuous maximum).
    #[arg(long)]
    pub fit: Option<String>,
    /// corrsum: σ in px of the Gaussian that smooths the summed correlation plane around its
    /// maximum before the sub-pixel fit, against peak locking (default 1; 0 = off).
    #[arg(long, value_name = "PX")]
    pub peak_smoothing: Option<f64>,
    /// corrsum: keep the events' positions sub-pixel wherever a predictor shifts and deforms
    /// the windows (later passes, repeated last pass, secondary-peak re-evaluation; 3×3
    /// spread voxels instead of rounding to pixels): lower random error (simulated turntable
    /// RMS 0.027 → 0.016 px/ms), about twice the processing time of those passes.
    #[arg(long)]
    pub subpixel_shift: bool,
    /// corrsum: voxel value, binary (one per pixel and time slice holding any event, as in
    /// the paper; the default) or count (its number of events). Together with
    /// --subpixel-shift the most accurate setting (simulated turntable, default passes,
    /// τ = 3 ms: RMS 0.018–0.021 px/ms without either option, 0.007–0.010 with both).
    #[arg(long, value_name = "binary|count")]
    pub weighting: Option<String>,
    /// motion: how the contrast maximum is found: newton (analytic gradient and Hessian from
    /// an event-pair vote, about three evaluations; the default) or grid (the paper's coarse
    /// grid and 5×5 refinement, 100–200 evaluations).
    #[arg(long, value_name = "METHOD")]
    pub motion_search: Option<String>,
    /// motion: half-width of the velocity search range in px/ms (default: window/slab,
    /// a quarter of it around a previous pass's prediction).
    #[arg(long, value_name = "PX_PER_MS")]
    pub search_range: Option<f64>,
    /// Normalized median test threshold (Westerweel & Scarano 2005; default 2).
    #[arg(long)]
    pub median_threshold: Option<f64>,
    /// Normalized median test ε in px/ms (default 0.1); in px for image pairs without --dt.
    #[arg(long)]
    pub median_epsilon: Option<f64>,
    /// Flag windows with fewer events (piv: fewer non-zero pixels in the first frame).
    #[arg(long)]
    pub min_events: Option<u32>,
    /// Flag correlation peaks whose first/second peak ratio is lower.
    #[arg(long)]
    pub min_peak_ratio: Option<f64>,
    /// Replace outliers of the last pass by interpolation of their neighbours (they keep
    /// their flag plus `replaced`).
    #[arg(long)]
    pub replace: bool,
    /// Keep the last pass's median-test outliers flagged instead of re-evaluating them on a
    /// lower correlation peak near their neighbours' median (corrsum, multi-pass runs;
    /// accepted vectors are valid, their peak_ratio is their peak over the highest other one).
    #[arg(long)]
    pub no_secondary_peaks: bool,
    /// Calibration: millimetres per pixel; outputs then give mm and m/s.
    #[arg(long)]
    pub mm_per_px: Option<f64>,
    /// Calibration: image point X,Y (px) of the physical origin (default 0,0).
    #[arg(long, value_parser = parse_point, value_name = "X,Y")]
    pub origin: Option<[f64; 2]>,
    /// Calibration: physical y axis upwards (flips y and v together).
    #[arg(long)]
    pub y_up: bool,
    #[command(flatten)]
    pub input: InputArgs,
}

fn parse_duration(text: &str) -> Result<Duration, String> {
    ebiv::units::parse_us(text).map(Duration)
}

fn parse_point(text: &str) -> Result<[f64; 2], String> {
    let v: Vec<Option<f64>> = text.split(',').map(|s| s.trim().parse().ok()).collect();
    match v.as_slice() {
        [Some(x), Some(y)] => Ok([*x, *y]),
        _ => Err(format!("`{text}` is not X,Y")),
    }
}

impl ProcessArgs {
    /// The flags as a configuration layer.
    fn as_config(&self) -> ProcessConfig {
        let validation = (self.median_threshold.is_some()
            || self.median_epsilon.is_some()
            || self.min_events.is_some()
            || self.min_peak_ratio.is_some())
        .then_some(());
        ProcessConfig {
            input: self.file.clone(),
            method: self.method.clone(),
            window: self.window.clone(),
            step: self.step.clone(),
            slab: self.slab,
            tau: self.tau,
            slices: self.slices,
            time: self.time.clone(),
            absolute_time: self.absolute_time.then_some(true),
            polarity: self.polarity.clone(),
            roi: self.roi.clone(),
            output: self.output.clone(),
            png: self.png.clone(),
            fit: self.fit.clone(),
            peak_smoothing: self.peak_smoothing,
            subpixel_shift: self.subpixel_shift.then_some(true),
            weighting: self.weighting.clone(),
            motion_search: self.motion_search.clone(),
            search_range: self.search_range,
            replace: self.replace.then_some(true),
            secondary_peaks: self.no_secondary_peaks.then_some(false),
            mm_per_px: self.mm_per_px,
            origin: self.origin,
            y_up: self.y_up.then_some(true),
            mask: self.mask.clone(),
            images: self.images.clone(),
            overlap: self.overlap,
            correlation: self.correlation.clone(),
            deformation: self.deformation.clone(),
            interpolation: self.interpolation.clone(),
            iterations: self.iterations,
            sequence: self.sequence.then_some(true),
            ensemble: self.ensemble.then_some(true),
            dt: self.dt,
            exposure: self.exposure,
            frame_step: self.frame_step,
            frame_kind: self.frame_kind.clone(),
            splat: self.splat,
            pairs: self.pairs,
            pulse_hz: self.pulse_hz,
            validation: validation.map(|_| Default::default()),
            corrsum: None,
            motion: None,
        }
    }
}

pub fn run(args: &ProcessArgs) -> Result<(), ebiv::Error> {
    let file_config = match &args.config {
        Some(path) => ProcessConfig::load(path)?,
        None => ProcessConfig::default(),
    };
    let mut config = file_config.clone().overridden_by(args.as_config());
    // Validation flags override single keys of the file's [validation] section.
    let mut validation = file_config.validation.unwrap_or_default();
    if let Some(v) = args.median_threshold {
        validation.median_threshold = v;
    }
    if let Some(v) = args.median_epsilon {
        validation.median_epsilon = v;
    }
    if let Some(v) = args.min_events {
        validation.min_events = v;
    }
    if let Some(v) = args.min_peak_ratio {
        validation.min_peak_ratio = v;
    }
    config.validation = Some(validation);
    let settings = Settings::from_config(&config)?;
    run_config(&settings, &args.input.read_options()?)
}

/// Write a commented configuration file for `ebiv process --config`.
#[derive(Debug, Args)]
pub struct InitArgs {
    /// File to write.
    #[arg(default_value = "ebiv.toml")]
    pub output: PathBuf,
    /// Overwrite an existing file.
    #[arg(long)]
    pub force: bool,
}

pub fn init(args: &InitArgs) -> Result<(), ebiv::Error> {
    if args.output.exists() && !args.force {
        return Err(ebiv::Error::parameter(
            "output",
            format!(
                "{} exists; use --force to overwrite it",
                args.output.display()
            ),
        ));
    }
    std::fs::write(&args.output, super::process_config::TEMPLATE)
        .map_err(|e| ebiv::Error::io(&args.output, e))?;
    println!(
        "wrote {}: edit it, then run `ebiv process --config {}`",
        args.output.display(),
        args.output.display()
    );
    Ok(())
}
