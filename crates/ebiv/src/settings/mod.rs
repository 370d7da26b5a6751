//! The settings of a velocity measurement: one schema for the library, the command line,
//! the configuration file and the `ebiv init` template.
//!
//! Each setting is defined once, below, as a field of [`ProcessSettings`]: its type, its
//! default, its help text (the doc comment), the placeholder of its value and the check of
//! its range. [`settings()`] describes them all; the CLI builds its `ebiv process` flags from
//! that description, [`ProcessSettings::apply_table`] reads configuration files with it, and
//! [`template`] writes the commented file. Keys are kebab-case and durations take units
//! everywhere (`slab = "10ms"`, `--slab 10ms`). [`ProcessSettings::resolve`] turns the
//! settings into the parameters of the estimators and of the multi-pass engine.

mod checks;
mod memory;
mod resolve;
mod run;
mod table;
mod value;

pub use crate::process::FieldTimes;
pub use memory::{spread_field_times, TimesFor};
pub use resolve::{EstimatorTask, Resolved, Source};
pub use run::{describe_piv, Measurement, RunObserver, RunPlan};
pub use table::{find, template, Setting};
pub use value::{Duration, Kind, PixelList, Point, SettingValue, SlabLength, TextList};

use crate::denoise::{DenoiseFilters, DenoiseSettings};
use crate::derived::DerivedList;
use crate::estimate::corrsum::{CorrKernel, Weighting};
use crate::estimate::motion::{Objective, SearchMethod};
use crate::event::PolaritySelection;
use crate::filter::Roi;
use crate::frame::events::FrameKind;
use crate::peak::SubPixelFit;
use crate::piv::{CorrelationKind, DeformationMode, Interpolation};
use crate::process::Method;
use checks::*;
use std::path::PathBuf;
use std::sync::OnceLock;

/// Defines [`ProcessSettings`], its `Default` and the table of [`Setting`]s from one list.
macro_rules! settings {
    ($(
        group $group:literal {
            $(
                $(#[doc = $doc:literal])*
                $field:ident : $ty:ty = $default:expr ; $value_name:literal
                $(, short $short:literal)?
                $(, alias $alias:literal)*
                $(, check $check:expr)?
                $(, positional $positional:literal)? ;
            )*
        }
    )*) => {
        /// Every setting of `ebiv process`, with its default. See the module documentation.
        #[derive(Debug, Clone, PartialEq)]
        pub struct ProcessSettings {
            $($( $(#[doc = $doc])* pub $field: $ty, )*)*
        }

        impl Default for ProcessSettings {
            fn default() -> Self {
                ProcessSettings { $($( $field: $default, )*)* }
            }
        }

        fn build_settings() -> Vec<Setting> {
            vec![$($(
                Setting {
                    key: kebab(stringify!($field)),
                    aliases: &[$($alias),*],
                    short: None $(.or(Some($short)))?,
                    group: $group,
                    help: help_text(&[$($doc),*]),
                    value_name: $value_name,
                    kind: <$ty as SettingValue>::KIND,
                    positional: false $(|| $positional)?,
                    get: |s| s.$field.to_toml(),
                    set: |s, v| {
                        let value = <$ty as SettingValue>::from_toml(v)?;
                        $( ($check)(&value)?; )?
                        s.$field = value;
                        Ok(())
                    },
                    set_texts: |s, texts| {
                        let value = <$ty as SettingValue>::from_texts(texts)?;
                        $( ($check)(&value)?; )?
                        s.$field = value;
                        Ok(())
                    },
                },
            )*)*]
        }
    };
}

settings! {
    group "Input and output" {
        /// The recording (any format `ebiv info` reads); not needed with `images`.
        input: Option<PathBuf> = None; "FILE", positional true;
        /// Output file: .nc (NetCDF), .csv, .npz, .dat (Tecplot) or .vtk.
        output: PathBuf = PathBuf::from("flow.nc"); "FILE", short 'o';
        /// Folder for figures: a vector map per field over its event image, histograms of u
        /// and v, and an animated GIF of the series.
        png: Option<PathBuf> = None; "DIR";
        /// Vector maps in `png`: draw every Nth arrow in x and y (1: every vector). Default:
        /// thinned so that arrows are at least 16 px apart and at most 40 span the grid.
        arrow_stride: Option<u32> = None; "N", check at_least_one_if_given;
        /// Mask image of the sensor's size (PNG, TIFF, BMP): non-zero pixels are left out;
        /// windows centred on them are flagged `masked`.
        mask: Option<PathBuf> = None; "IMAGE";
        /// Quantities derived from the velocity gradient, added to the output (.nc, .csv,
        /// .npz): vorticity, divergence, e_xx, e_yy, e_xy, swirling_strength, strain (the
        /// three e) or all, comma-separated (docs/derived.md). With `png`, also a map of the
        /// first of them per field.
        derive: Option<DerivedList> = None; "QTY[,QTY..]";
    }
    group "Method and time" {
        /// Estimator: corrsum (sum of correlation, fast), motion (motion compensation), piv
        /// (cross-correlation PIV of frames rebuilt from the events, or of `images`) or pulsed
        /// (PIV of one frame per light pulse, pulse timing detected).
        method: Method = Method::CorrSum; "METHOD";
        /// Time slab T of one field (corrsum, motion), or auto: each window's slab chosen
        /// from its velocity so that its particles move about `slab-displacement` px in it,
        /// between `slab-min` and `slab-max` (every vector records its slab, `slab_us`).
        slab: SlabLength = SlabLength::Fixed(Duration::ms(10)); "DUR|auto", check positive_slab;
        /// Field centre times START:END:STEP (END inclusive), from the first event, e.g.
        /// 60ms:60ms:1ms for one field at 60 ms; START or END may be left out (::5ms).
        /// Default: every field that fits in the recording, one per slab.
        time: Option<FieldTimes> = None; "START:END:STEP";
        /// Read `time` as camera time stamps rather than from the first event.
        absolute_time: bool = false; "";
        /// Events used: pos, neg or both (pos, as in the EBIV paper).
        polarity: PolaritySelection = PolaritySelection::Positive; "POL";
        /// Leave out of each field (corrsum, motion) the pixels that fire through most of its
        /// time span while none of their 8 neighbours does: hot pixels, which would show as
        /// vectors at rest in sparse windows (no particle image is a single pixel).
        drop_lone_pixels: bool = true; "";
    }
    group "Denoising" {
        /// Filters that remove noise events as the recording is read, before anything else:
        /// hot-pixels, refractory, correlation (they run in this order), all, or none
        /// (docs/denoise.md).
        denoise: DenoiseFilters = DenoiseFilters::default(); "FILTER[,FILTER..]";
        /// Correlation filter: an event is kept only if one of its 8 neighbours fired at
        /// most this long before it (Delbrück 2008).
        denoise_dt: Duration = Duration::ms(1); "DUR", check positive_duration;
        /// Refractory filter: events of a pixel less than this long after its previous kept
        /// event are removed.
        denoise_refractory: Duration = Duration(10); "DUR", check positive_duration;
        /// Hot-pixel filter: a pixel is hot when its event count over the learning interval
        /// is more than this many times the median count of its 8 neighbours (and at least
        /// 10, spread over at least half the interval).
        denoise_hot_factor: f64 = 5.0; "FACTOR", check above_one;
        /// Hot-pixel filter: the learning interval, from the first event of the recording
        /// (the whole recording when it is shorter).
        denoise_hot_learn: Duration = Duration::ms(1000); "DUR", check positive_duration;
    }
    group "Adaptive slab (slab = auto)" {
        /// Shortest slab: the sensor's latency or longer (an event camera's pixels respond
        /// within about 0.1–1 ms, longer in dim light), and long enough to hold events.
        slab_min: Duration = Duration::ms(1); "DUR", check positive_duration;
        /// Longest slab: how long a slow flow may be assumed steady.
        slab_max: Duration = Duration::ms(200); "DUR", check positive_duration;
        /// Slab of the first pass, whose velocities choose the slabs of the later passes;
        /// also the default step between fields.
        slab_probe: Duration = Duration::ms(10); "DUR", check positive_duration;
        /// Displacement |v|·T over the slab, px, that the choice aims at from below
        /// (sum of correlation's delay τ scales with the slab, in the ratio tau/slab-probe).
        slab_displacement: f64 = 20.0; "PX", check positive;
    }
    group "Interrogation windows and passes" {
        /// Window size in px, one per pass, largest first (e.g. 40 or 64,40); the first
        /// passes predict the velocity for the next. Default: 64,40 (piv and pulsed:
        /// 64,32,16).
        window: Option<PixelList> = None; "PX[,PX..]", alias "passes", check positive_pixels;
        /// Grid step in px, one per pass. Default: window × (1 − overlap).
        step: Option<PixelList> = None; "PX[,PX..]", check positive_pixels;
        /// Overlap of neighbouring windows, 0 ≤ overlap < 1, when `step` is not given.
        overlap: f64 = 0.5; "FRACTION", check overlap_fraction;
        /// Region the windows must lie in: x,y,width,height (px).
        roi: Option<Roi> = None; "X,Y,W,H";
        /// Sub-pixel peak fit: gauss3, parabolic or gauss2d. Default: gauss2d for corrsum,
        /// gauss3 for motion (where its grid search runs) and PIV.
        fit: Option<SubPixelFit> = None; "FIT";
        /// Repetitions of the last pass of a multi-pass run at most, each with the previous
        /// result as predictor, until the field changes by less than `repeat-tolerance`
        /// (PIV: also after a single pass).
        last_pass_repeats: u32 = 2; "N", alias "iterations", check at_most_twenty;
        /// Mean change of the valid vectors between two repetitions of the last pass below
        /// which they stop, in the field's unit (px/ms; px for image pairs without `dt`).
        /// Default: 0.005 for the event methods, 0.01 for PIV.
        repeat_tolerance: Option<f64> = None; "VALUE", check non_negative;
        /// Smoothing of the predictor between passes, in grid nodes (0 = none). Default: 1
        /// for the event methods (σ of the weights of a local linear fit), 0.5 for PIV (σ of
        /// a Gaussian filter).
        predictor_smoothing: Option<f64> = None; "NODES", check non_negative;
        /// Deform the events of later passes by the predictor's velocity gradient, so that
        /// vectors refer to their window centre (corrsum, motion).
        deform: bool = true; "";
        /// Replace outliers of the last pass by interpolation of their neighbours (they keep
        /// their flag plus `replaced`).
        replace: bool = false; "";
        /// Re-evaluate the last pass's median-test outliers on a lower correlation peak near
        /// their neighbours' median (corrsum, multi-pass runs).
        secondary_peaks: bool = true; "";
        /// Estimate each vector's standard uncertainty `u_unc`, `v_unc` on the last pass
        /// (docs/uncertainty.md). Off, they are NaN, and sum of correlation runs about 1.5
        /// times as fast.
        uncertainty: bool = true; "";
    }
    group "Validation" {
        /// Normalized median test threshold (Westerweel & Scarano 2005).
        median_threshold: f64 = 2.0; "VALUE", check positive;
        /// Normalized median test ε in px/ms (px for image pairs without `dt`).
        median_epsilon: f64 = 0.1; "VALUE", check non_negative;
        /// Flag windows with fewer events (piv: fewer non-zero pixels in the first frame);
        /// 0 = off (default: the event estimators test the evidence behind each peak
        /// themselves, which a fixed event count cannot).
        min_events: u32 = 0; "N";
        /// Flag correlation peaks whose first/second peak ratio is lower; 0 = off (default:
        /// the event estimators test their own peaks; a lone spike of a chance coincidence
        /// has a high ratio, a good peak of a sparse window one near 1).
        min_peak_ratio: f64 = 0.0; "RATIO", check non_negative;
        /// Flag vectors faster than this, px/ms (px for image pairs without `dt`).
        max_velocity: Option<f64> = None; "VALUE", check positive;
    }
    group "Sum of correlation (corrsum)" {
        /// Delay τ between the two sub-volumes.
        tau: Duration = Duration::ms(3); "DUR", check positive_duration;
        /// Time slices N_T per sub-volume.
        slices: u32 = 20; "N", check at_least_one;
        /// Voxel value: binary (one per pixel and time slice holding any event, as in the
        /// paper) or count (its number of events).
        weighting: Weighting = Weighting::Binary; "binary|count";
        /// σ in px of the Gaussian that smooths the summed correlation plane around its
        /// maximum before the sub-pixel fit, against peak locking (0 = off).
        peak_smoothing: f64 = 1.0; "PX", check non_negative;
        /// Keep the events' positions sub-pixel wherever a predictor shifts and deforms the
        /// windows: lower random error, about twice the processing time of those passes.
        subpixel_shift: bool = false; "";
        /// Largest displacement searched from the window offset, px per axis. Default: a
        /// third of the window.
        search_radius: Option<u32> = None; "PX", check at_least_one_px;
        /// Correlation kernel: auto (direct for sparse windows, FFT for dense ones), fft or
        /// direct; all give the same plane.
        kernel: CorrKernel = CorrKernel::Auto; "KERNEL";
    }
    group "Motion compensation (motion)" {
        /// How the contrast maximum is found: newton (analytic gradient and Hessian, about
        /// three evaluations per start; started from a sum of correlation, an event-pair
        /// vote and zero velocity, the highest maximum wins) or grid (the paper's coarse
        /// grid over the whole range and 5×5 refinement, also from the sum-of-correlation
        /// start; several hundred evaluations over the default range).
        motion_search: SearchMethod = SearchMethod::Newton; "METHOD";
        /// Half-width of the velocity search range in px/ms, per component. Default:
        /// 4 × window/slab (particles crossing the window within the slab still leave a
        /// trail across it), window/(4 × slab) around a previous pass's prediction. Maxima
        /// at its edge, and windows whose events move faster, are flagged out_of_range.
        search_range: Option<f64> = None; "PX_PER_MS", check positive;
        /// Sharpness objective of the warped event image: variance, sum-of-squares,
        /// sum-exp, r1, isoa or max-accumulation.
        objective: Objective = Objective::Variance; "OBJECTIVE";
        /// Step of the grid search's coarse candidates, px/ms.
        coarse_step: f64 = 0.25; "PX_PER_MS", check positive;
        /// Smallest refinement step of the grid search, px/ms.
        final_step: f64 = 0.05; "PX_PER_MS", check positive;
    }
    group "Both event estimators" {
        /// Windows with fewer events (corrsum: mean per sub-volume) are flagged `few_events`
        /// by the estimator itself (corrsum also flags a peak with fewer than 12 coincident
        /// voxel pairs behind it).
        estimator_min_events: u32 = 10; "N";
    }
    group "PIV (piv, pulsed)" {
        /// Image files or patterns (frames/*.png) instead of a recording (method piv); pairs
        /// (1,2), (3,4), …; u and v are then displacements in px (velocities with `dt`).
        images: Option<TextList> = None; "IMAGE";
        /// Image input: pair the images as a sequence (1,2), (2,3), …
        sequence: bool = false; "";
        /// Image input: sum the correlation planes of all pairs into one field (ensemble
        /// PIV).
        ensemble: bool = false; "";
        /// Image input: time between the two frames of a pair; outputs velocities in px/ms.
        dt: Option<Duration> = None; "DUR", check positive_duration;
        /// Correlation: circular or linear (zero-padded).
        correlation: CorrelationKind = CorrelationKind::Circular; "KIND";
        /// Window deformation: symmetric (both frames by ∓½ the predictor) or second.
        deformation: DeformationMode = DeformationMode::Symmetric; "MODE";
        /// Image interpolation for the deformation: quintic, cubic or linear.
        interpolation: Interpolation = Interpolation::Quintic; "KIND";
        /// Events: exposure of one rebuilt frame.
        exposure: Duration = Duration(1500); "DUR", check positive_duration;
        /// Events: time Δt between consecutive frames.
        frame_step: Duration = Duration(2500); "DUR", check positive_duration;
        /// Events: frame kind, count, binary or time-surface.
        frame_kind: FrameKind = FrameKind::Count; "KIND";
        /// Events: spread each event over a Gaussian of this σ in px (0 = none).
        splat: f64 = 0.0; "PX", check splat_sigma;
        /// Events: frame pairs per field whose correlation planes are summed (3 for the
        /// paper's four-frame sequences).
        pairs: u32 = 1; "N", check frame_pairs;
        /// Pulsed: nominal pulse frequency in Hz. Default: found from the events or triggers.
        pulse_hz: Option<f64> = None; "HZ", check positive;
    }
    group "Calibration" {
        /// Millimetres per pixel; outputs then give mm and m/s.
        mm_per_px: Option<f64> = None; "MM", check positive;
        /// Image point X,Y (px) of the physical origin. Default: 0,0.
        origin: Option<Point> = None; "X,Y";
        /// Physical y axis upwards (flips y and v together). VTK files (.vtk) have y up in
        /// any case, so that ParaView shows the image as the camera saw it: without y-up
        /// they hold y = -row (mm: -y) and v positive up.
        y_up: bool = false; "";
    }
}

/// The heading of the denoising settings: the commands that read recordings without
/// measuring (`ebiv frames`, `render`, `convert`, `filter`) take these settings alone.
pub const DENOISE_GROUP: &str = "Denoising";

impl ProcessSettings {
    /// The denoising filters, `None` when none runs.
    pub fn denoise_settings(&self) -> Option<DenoiseSettings> {
        self.denoise.any().then_some(DenoiseSettings {
            filters: self.denoise,
            correlation_dt_us: self.denoise_dt.0,
            refractory_us: self.denoise_refractory.0,
            hot_pixel_factor: self.denoise_hot_factor,
            hot_pixel_learn_us: self.denoise_hot_learn.0,
        })
    }
}

/// Every setting, in the order of `--help` and the template.
pub fn settings() -> &'static [Setting] {
    static SETTINGS: OnceLock<Vec<Setting>> = OnceLock::new();
    SETTINGS.get_or_init(build_settings)
}

/// `median_threshold` → `median-threshold`, made once per setting.
fn kebab(field: &str) -> &'static str {
    Box::leak(field.replace('_', "-").into_boxed_str())
}

/// The doc comment's lines as one paragraph of help text.
fn help_text(lines: &[&str]) -> String {
    lines.iter().map(|l| l.trim()).collect::<Vec<_>>().join(" ")
}
