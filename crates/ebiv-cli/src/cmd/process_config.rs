//! The settings of `ebiv process`: one struct read from a TOML file (`--config`) and
//! overridden by command-line flags of the same names; `ebiv init` writes a commented file.

use ebiv::estimate::corrsum::CorrSumParams;
use ebiv::estimate::motion::MotionParams;
use ebiv::validate::ValidationParams;
use serde::Deserialize;
use std::path::PathBuf;

/// Every setting of a run; `None` means "not given here" (a later source or the default
/// decides). Keys are the long flag names.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct ProcessConfig {
    pub input: Option<PathBuf>,
    pub method: Option<String>,
    #[serde(alias = "passes")]
    pub window: Option<ListOfU32>,
    pub step: Option<ListOfU32>,
    pub slab: Option<Duration>,
    pub tau: Option<Duration>,
    pub slices: Option<u32>,
    pub time: Option<String>,
    pub absolute_time: Option<bool>,
    pub polarity: Option<String>,
    pub roi: Option<String>,
    pub output: Option<PathBuf>,
    pub png: Option<PathBuf>,
    pub fit: Option<String>,
    pub peak_smoothing: Option<f64>,
    pub subpixel_shift: Option<bool>,
    pub weighting: Option<String>,
    pub motion_search: Option<String>,
    pub search_range: Option<f64>,
    pub replace: Option<bool>,
    pub secondary_peaks: Option<bool>,
    pub mm_per_px: Option<f64>,
    pub origin: Option<[f64; 2]>,
    pub y_up: Option<bool>,
    pub mask: Option<PathBuf>,
    pub images: Option<Vec<String>>,
    pub overlap: Option<f64>,
    pub correlation: Option<String>,
    pub deformation: Option<String>,
    pub interpolation: Option<String>,
    pub iterations: Option<u32>,
    pub sequence: Option<bool>,
    pub ensemble: Option<bool>,
    pub dt: Option<Duration>,
    pub exposure: Option<Duration>,
    pub frame_step: Option<Duration>,
    pub frame_kind: Option<String>,
    pub splat: Option<f64>,
    pub pairs: Option<u32>,
    pub pulse_hz: Option<f64>,
    pub validation: Option<ValidationParams>,
    pub corrsum: Option<CorrSumParams>,
    pub motion: Option<MotionParams>,
}

/// A duration written with units (`"10ms"`) or as µs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub struct Duration(#[serde(with = "ebiv::units::serde_us")] pub i64);

/// One number or a list of numbers (one per pass).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(untagged)]
pub enum ListOfU32 {
    One(u32),
    Many(Vec<u32>),
}

impl ListOfU32 {
    pub fn values(&self) -> Vec<u32> {
        match self {
            ListOfU32::One(v) => vec![*v],
            ListOfU32::Many(v) => v.clone(),
        }
    }

    /// Parse `40` or `64,32` (flags).
    pub fn parse(text: &str) -> Result<ListOfU32, String> {
        let values: Result<Vec<u32>, _> = text.split(',').map(|s| s.trim().parse()).collect();
        match values {
            Ok(v) if !v.is_empty() => Ok(ListOfU32::Many(v)),
            _ => Err(format!(
                "`{text}` is not a pixel count or comma-separated list of them"
            )),
        }
    }
}

impl ProcessConfig {
    /// Read a TOML configuration file.
    pub fn load(path: &std::path::Path) -> Result<Self, ebiv::Error> {
        let text = std::fs::read_to_string(path).map_err(|e| ebiv::Error::io(path, e))?;
        toml::from_str(&text).map_err(|e| {
            ebiv::Error::parameter("config", format!("{}: {}", path.display(), e.message()))
        })
    }

    /// `self` with every setting that `over` gives replaced by `over`'s.
    pub fn overridden_by(self, over: ProcessConfig) -> ProcessConfig {
        macro_rules! pick {
            ($($f:ident),*) => { ProcessConfig { $($f: over.$f.or(self.$f)),* } };
        }
        pick!(
            input,
            method,
            window,
            step,
            slab,
            tau,
            slices,
            time,
            absolute_time,
            polarity,
            roi,
            output,
            png,
            fit,
            peak_smoothing,
            subpixel_shift,
            weighting,
            motion_search,
            search_range,
            replace,
            secondary_peaks,
            mm_per_px,
            origin,
            y_up,
            mask,
            images,
            overlap,
            correlation,
            deformation,
            interpolation,
            iterations,
            sequence,
            ensemble,
            dt,
            exposure,
            frame_step,
            frame_kind,
            splat,
            pairs,
            pulse_hz,
            validation,
            corrsum,
            motion
        )
    }
}

/// The file `ebiv init` writes: every setting, commented, with its default.
pub const TEMPLATE: &str = r#"# ebiv process configuration: `ebiv process --config THIS_FILE` (flags override keys).
# Durations take units (10ms, 250us, 1.5s); lengths are pixels; velocities px/ms.
# Image coordinates: x to the right, y down, pixel centres at integers.

# input = "recording.raw"       # the recording (or give it on the command line)
method = "corrsum"              # corrsum (sum of correlation), motion (motion compensation),
                                # piv (PIV of frames rebuilt from events, or of --images)
                                # or pulsed (PIV of one frame per light pulse)

# Interrogation windows and grid step, px; a list gives one pass each, largest first:
# the first pass predicts the velocity for the next (window offset / search centre).
window = [64, 40]               # piv default: [64, 32, 16]
# step = [32, 20]               # default: window × (1 − overlap), overlap 0.5

slab = "10ms"                   # time slab T of one field
tau = "3ms"                     # corrsum: delay between the two sub-volumes
slices = 20                     # corrsum: time slices N_T per sub-volume
# time = "10ms:90ms:5ms"        # field centre times START:END:STEP, END inclusive, from the
#                               # first event (absolute-time = true: camera time);
#                               # default: every field that fits, one per slab
polarity = "pos"                # pos, neg or both
# roi = "0,0,640,480"           # x,y,width,height the windows must lie in
output = "flow.nc"              # .nc, .csv, .npz, .dat (Tecplot) or .vtk
# png = "figures"               # folder for vector maps, histograms and an animation
# fit = "gauss2d"              # sub-pixel peak fit: gauss3, parabolic or gauss2d
#                               # (default: gauss2d for corrsum, gauss3 for motion)
# peak-smoothing = 1.0          # corrsum: Gaussian σ (px) smoothing the plane near its peak
#                               # before the fit, against peak locking; 0 = off
# subpixel-shift = false        # corrsum: keep event positions sub-pixel where a predictor
#                               # shifts/deforms the windows (lower random error, ~2x the
#                               # time of those passes)
# weighting = "binary"          # corrsum: voxel value, binary (paper) or count (events per
#                               # voxel; with subpixel-shift the lowest random error)
# motion-search = "newton"      # motion: newton (default, ~3 evaluations per window) or grid
#                               # (the paper's coarse grid + 5x5 refinement)
# search-range = 4.0            # motion: half-width of the velocity search, px/ms
#                               # (default: window / slab, a quarter of it around a predictor)
replace = false                 # replace outliers of the last pass by interpolation
secondary-peaks = true          # corrsum, multi-pass: re-evaluate the last pass's
                                # median-test outliers on a lower correlation peak (>= half
                                # the highest) near their neighbours' median; flag
                                # --no-secondary-peaks turns it off

# mask = "mask.png"             # image of the sensor size; non-zero pixels are left out

# PIV (method = "piv" or "pulsed"); windows above are the passes, e.g. [64, 32, 16]
# images = ["a.bmp", "b.bmp"]   # image files or patterns (frame_*.png) instead of events:
#                               # pairs (1,2), (3,4), …; u, v are displacements in px
# sequence = false              # images: pairs (1,2), (2,3), … instead
# ensemble = false              # images: sum the correlation planes of all pairs, one field
# dt = "1ms"                    # images: time between the frames: velocities instead
# overlap = 0.5                 # step = window × (1 − overlap) when `step` is not given
# correlation = "circular"      # circular or linear (zero-padded)
# deformation = "symmetric"     # symmetric (both frames by ∓½ predictor) or second
# interpolation = "quintic"     # quintic, cubic (B-splines) or linear image resampling
# iterations = 2                # repetitions of the last pass at most
# exposure = "1.5ms"            # events: exposure of one rebuilt frame
# frame-step = "2.5ms"          # events: time between frames (Δt)
# frame-kind = "count"          # events: count, binary or time-surface
# splat = 0.0                   # events: Gaussian σ (px) each event is spread over
# pairs = 1                     # events: frame pairs per field, planes summed (3 = 4 frames)
# pulse-hz = 2000.0             # pulsed: nominal pulse frequency (default: detected)

# Calibration: positions in mm and velocities in m/s in the outputs
# mm-per-px = 0.05
# origin = [0.0, 720.0]         # image point (px) of the physical origin
# y-up = true                   # physical y upwards (flips y and v together)

[validation]
median_threshold = 2.0          # normalized median test (Westerweel & Scarano 2005)
median_epsilon = 0.1            # px/ms (px for image pairs without dt)
min_events = 0                  # flag windows with fewer events
min_peak_ratio = 0.0            # flag correlation peaks below this first/second ratio
# max_velocity = 20.0           # flag vectors faster than this, px/ms

# Expert settings of the estimators (the top-level keys above take precedence):
# [corrsum]
# kernel = "auto"               # auto, fft or direct
# min_events = 10
# [motion]
# objective = "variance"
# coarse_step = 0.25            # px/ms
# final_step = 0.05             # px/ms
"#;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn template_parses_and_flags_override_it() {
        let c: ProcessConfig = toml::from_str(TEMPLATE).unwrap();
        assert_eq!(c.window.as_ref().unwrap().values(), vec![64, 40]);
        assert_eq!(c.slab, Some(Duration(10_000)));
        let over = ProcessConfig {
            window: Some(ListOfU32::One(32)),
            ..Default::default()
        };
        let merged = c.overridden_by(over);
        assert_eq!(merged.window.unwrap().values(), vec![32]);
        assert_eq!(merged.tau, Some(Duration(3000)));
        assert!(toml::from_str::<ProcessConfig>("windw = 3").is_err());
    }
}
