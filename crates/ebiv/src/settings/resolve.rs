//! From [`ProcessSettings`] to the parameters of the estimators and of the multi-pass
//! engine: the defaults that depend on the method are filled in, and settings are checked
//! against each other.

use super::{ProcessSettings, SlabLength};
use crate::derived::DerivedQuantity;
use crate::error::{Error, Result};
use crate::estimate::adaptive::{AdaptiveSlab, AdaptiveSlabParams};
use crate::estimate::corrsum::{CorrSumParams, SumOfCorrelation};
use crate::estimate::motion::{ContrastMaximization, MotionParams};
use crate::estimate::Estimator;
use crate::event::Geometry;
use crate::field::{Calibration, FieldSeries};
use crate::frame::events::FrameSpec;
use crate::grid::{GridSpec, Mask};
use crate::io::{EventSource, ReadOptions};
use crate::piv::PivParams;
use crate::process::{plan_fields, Method, PlannedFields, ProcessParams};
use crate::validate::ValidationParams;
use std::path::PathBuf;

/// Window sizes of the event methods when `window` is not given, px.
pub const EVENT_WINDOWS: [u32; 2] = [64, 40];
/// Window sizes of PIV when `window` is not given, px.
pub const PIV_WINDOWS: [u32; 3] = [64, 32, 16];
/// `repeat-tolerance` of the event methods when not given, px/ms.
pub const EVENT_REPEAT_TOLERANCE: f64 = 0.005;
/// `repeat-tolerance` of PIV when not given, px (PIVlab stops at 0.025 px).
pub const PIV_REPEAT_TOLERANCE: f64 = 0.01;
/// `predictor-smoothing` of the event methods when not given, grid nodes.
pub const EVENT_PREDICTOR_SMOOTHING: f64 = 1.0;
/// `predictor-smoothing` of PIV when not given, grid nodes.
pub const PIV_PREDICTOR_SMOOTHING: f64 = 0.5;

/// Where the events or images come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// An event recording.
    Recording(PathBuf),
    /// Image files or patterns, for PIV.
    Images(Vec<String>),
}

/// Everything a run needs, resolved and checked.
#[derive(Debug, Clone)]
pub struct Resolved {
    /// The recording or the images.
    pub source: Source,
    /// The estimator.
    pub method: Method,
    /// Sum of correlation's parameters (with `slab = auto`, those of the first pass's slab;
    /// [`CorrSumParams::with_slab`] gives the others).
    pub corrsum: CorrSumParams,
    /// Motion compensation's parameters (with `slab = auto`, those of the first pass's
    /// slab).
    pub motion: MotionParams,
    /// With `slab = auto`: the bounds and target of the slab of each window.
    pub adaptive: Option<AdaptiveSlabParams>,
    /// The multi-pass engine's parameters for the event methods (the mask is loaded when
    /// the sensor size is known).
    pub process: ProcessParams,
    /// The PIV engine's parameters (piv, pulsed).
    pub piv: PivParams,
    /// How frames are rebuilt from events (piv, pulsed).
    pub frames: FrameSpec,
    /// Time between rebuilt frames, µs.
    pub frame_step_us: i64,
    /// Frame pairs per field.
    pub pairs: u32,
    /// Nominal pulse frequency, Hz (pulsed).
    pub pulse_hz: Option<f64>,
    /// Image input: pairs (1,2), (2,3), … instead of (1,2), (3,4), ….
    pub sequence: bool,
    /// Image input: one field from all pairs.
    pub ensemble: bool,
    /// Image input: time between the frames of a pair, µs.
    pub dt_us: Option<i64>,
    /// Field times; `None`: every field that fits.
    pub time: Option<super::FieldTimes>,
    /// `time` in camera time rather than from the first event.
    pub absolute_time: bool,
    /// The output file.
    pub output: PathBuf,
    /// The folder for figures.
    pub png: Option<PathBuf>,
    /// Draw every Nth arrow of the vector maps; `None`: a readable density.
    pub arrow_stride: Option<u32>,
    /// Positions in mm and velocities in m/s.
    pub calibration: Option<Calibration>,
    /// The mask image.
    pub mask: Option<PathBuf>,
    /// Quantities derived from the velocity gradient, added to the series.
    pub derive: Vec<DerivedQuantity>,
    /// The filters the recording is read through, `None` when none runs.
    pub denoise: Option<crate::denoise::DenoiseSettings>,
}

impl Resolved {
    /// Give a measured `series` the run's calibration and derived quantities
    /// ([`crate::derived`]), as it is written.
    pub fn finish_series(&self, series: &mut FieldSeries) -> Result<()> {
        series.calibration = self.calibration;
        crate::derived::add_derived(series, &self.derive)
    }

    /// The recording, or the first image with image input (for messages).
    pub fn input_path(&self) -> PathBuf {
        match &self.source {
            Source::Recording(p) => p.clone(),
            Source::Images(images) => PathBuf::from(images.first().cloned().unwrap_or_default()),
        }
    }

    /// The recording as a source of events, read with `options` and the run's denoising.
    pub fn event_source(&self, options: &ReadOptions) -> EventSource {
        EventSource::file(self.input_path(), options).denoised(self.denoise)
    }

    /// Open `source` and plan its field times ([`plan_fields`]) for a method whose fields
    /// need `extent_us` = (before, after) µs of events around their times, one every
    /// `default_step` µs unless `time` says otherwise.
    pub fn plan_fields(
        &self,
        source: &EventSource,
        extent_us: (i64, i64),
        default_step: i64,
    ) -> Result<PlannedFields> {
        plan_fields(
            source,
            self.time,
            self.absolute_time,
            extent_us,
            default_step,
        )
    }

    /// The mask image for a sensor or frames of `geometry`, if one is given.
    pub fn mask_for(&self, geometry: Geometry) -> Result<Option<Mask>> {
        self.mask
            .as_deref()
            .map(|path| crate::frame::load_mask(path, geometry))
            .transpose()
    }

    /// The slab T of the event methods (with `slab = auto`: of the first pass), µs; the
    /// default step between fields.
    pub fn slab_us(&self) -> i64 {
        match self.method {
            Method::Motion => self.motion.slab_us,
            _ => self.corrsum.slab_us,
        }
    }
}

/// Work to do with the event estimator of a run, whatever its type: see
/// [`Resolved::with_event_estimator`].
pub trait EstimatorTask {
    /// What the work returns.
    type Output;
    /// Do the work with `estimator`.
    fn run<E: Estimator>(self, estimator: &E) -> Self::Output;
}

impl Resolved {
    /// Build the run's event estimator (sum of correlation or motion compensation, over one
    /// slab or, with `slab = auto`, a slab per window) and hand it to `task`. An error for
    /// the other methods, or parameters an estimator rejects.
    pub fn with_event_estimator<T: EstimatorTask>(&self, task: T) -> Result<T::Output> {
        let corrsum = |slab_us| SumOfCorrelation::new(self.corrsum.with_slab(slab_us));
        let motion = |slab_us| {
            ContrastMaximization::new(MotionParams {
                slab_us,
                ..self.motion.clone()
            })
        };
        Ok(match (self.method, self.adaptive) {
            (Method::CorrSum, None) => task.run(&SumOfCorrelation::new(self.corrsum)?),
            (Method::CorrSum, Some(a)) => task.run(&AdaptiveSlab::new(a, corrsum)?),
            (Method::Motion, None) => task.run(&ContrastMaximization::new(self.motion.clone())?),
            (Method::Motion, Some(a)) => task.run(&AdaptiveSlab::new(a, motion)?),
            (Method::Piv | Method::Pulsed, _) => {
                return Err(Error::parameter(
                    "method",
                    "piv and pulsed measure frames, not with an event estimator",
                ))
            }
        })
    }
}

impl ProcessSettings {
    /// The parameters of every part of a run, with method-dependent defaults filled in and
    /// the settings checked against each other. Errors name the setting's key.
    pub fn resolve(&self) -> Result<Resolved> {
        let method = self.method;
        let is_piv = matches!(method, Method::Piv | Method::Pulsed);
        let source = match (&self.input, &self.images) {
            (Some(_), Some(_)) => {
                return Err(Error::parameter(
                    "images",
                    "give either a recording or images, not both",
                ))
            }
            (_, Some(_)) if method != Method::Piv => {
                return Err(Error::parameter("images", "image input needs --method piv"))
            }
            (Some(path), None) => Source::Recording(path.clone()),
            (None, Some(images)) => Source::Images(images.0.clone()),
            (None, None) => {
                return Err(Error::parameter(
                    "input",
                    "no recording given (ebiv process FILE, or `input` in the config)",
                ))
            }
        };
        let passes = self.passes(is_piv)?;
        let validation = ValidationParams {
            median_threshold: self.median_threshold,
            median_epsilon: self.median_epsilon,
            min_events: self.min_events,
            min_peak_ratio: self.min_peak_ratio,
            max_velocity: self.max_velocity,
        };
        validation.check()?;

        let slab_us = self.slab.first_pass_us(self.slab_probe);
        let adaptive = match self.slab {
            SlabLength::Fixed(_) => None,
            SlabLength::Auto => {
                let adaptive = AdaptiveSlabParams {
                    min_us: self.slab_min.0,
                    max_us: self.slab_max.0,
                    probe_us: self.slab_probe.0,
                    displacement_px: self.slab_displacement,
                };
                adaptive.validate()?;
                Some(adaptive)
            }
        };
        let mut corrsum = CorrSumParams {
            slab_us,
            tau_us: self.tau.0,
            slices: self.slices,
            kernel: self.kernel,
            weighting: self.weighting,
            min_events: self.estimator_min_events,
            search_radius_px: self.search_radius,
            peak_smoothing_px: self.peak_smoothing,
            subpixel_shift: self.subpixel_shift,
            ..CorrSumParams::default()
        };
        let mut motion = MotionParams {
            slab_us,
            objective: self.objective,
            search_range: self.search_range,
            coarse_step: self.coarse_step,
            final_step: self.final_step,
            min_events: self.estimator_min_events,
            search: self.motion_search,
            ..MotionParams::default()
        };
        let mut piv = PivParams {
            passes: passes.clone(),
            correlation: self.correlation,
            deformation: self.deformation,
            interpolation: self.interpolation,
            validation: validation.clone(),
            replace_final: self.replace,
            predictor_smoothing: self.predictor_smoothing.unwrap_or(PIV_PREDICTOR_SMOOTHING),
            last_pass_repeats: self.last_pass_repeats,
            repeat_tolerance: self.repeat_tolerance.unwrap_or(PIV_REPEAT_TOLERANCE),
            uncertainty: self.uncertainty,
            ..PivParams::default()
        };
        if let Some(fit) = self.fit {
            corrsum.fit = fit;
            motion.fit = fit;
            piv.fit = fit;
        }
        if method == Method::CorrSum {
            corrsum.validate()?;
        }
        if method == Method::Motion {
            motion.validate()?;
        }
        let process = ProcessParams {
            passes,
            polarity: self.polarity,
            validation,
            replace_final: self.replace,
            predictor_smoothing: self
                .predictor_smoothing
                .unwrap_or(EVENT_PREDICTOR_SMOOTHING),
            mask: None,
            deform: self.deform,
            last_pass_repeats: self.last_pass_repeats,
            repeat_tolerance: self.repeat_tolerance.unwrap_or(EVENT_REPEAT_TOLERANCE),
            secondary_peaks: self.secondary_peaks,
            uncertainty: self.uncertainty,
            drop_lone_pixels: self.drop_lone_pixels,
        };
        if is_piv {
            piv.check()?;
        }
        let frames = FrameSpec {
            kind: self.frame_kind,
            exposure_us: self.exposure.0,
            polarity: self.polarity,
            splat_sigma: self.splat,
        };
        let denoise = self.denoise_settings();
        if let Some(d) = &denoise {
            d.check()?;
        }
        let calibration = match self.mm_per_px {
            Some(mm_per_px) => {
                let calibration = Calibration {
                    mm_per_px,
                    origin_px: self.origin.map(|p| p.0).unwrap_or([0.0, 0.0]),
                    y_up: self.y_up,
                };
                calibration.validate()?;
                Some(calibration)
            }
            None if self.origin.is_some() || self.y_up => {
                return Err(Error::parameter(
                    "mm-per-px",
                    "origin and y-up need a calibration scale (--mm-per-px)",
                ))
            }
            None => None,
        };
        let derive = self.derive.as_ref();
        if derive.is_some() {
            crate::derived::check_output(&self.output)?;
        }
        Ok(Resolved {
            source,
            method,
            corrsum,
            motion,
            adaptive,
            process,
            piv,
            frames,
            frame_step_us: self.frame_step.0,
            pairs: self.pairs,
            pulse_hz: self.pulse_hz,
            sequence: self.sequence,
            ensemble: self.ensemble,
            dt_us: self.dt.map(|d| d.0),
            time: self.time,
            absolute_time: self.absolute_time,
            output: self.output.clone(),
            png: self.png.clone(),
            arrow_stride: self.arrow_stride,
            calibration,
            mask: self.mask.clone(),
            derive: derive.map(|d| d.0.clone()).unwrap_or_default(),
            denoise,
        })
    }

    /// The grids of the passes: `window`, `step` (or the overlap's) and `roi`.
    fn passes(&self, is_piv: bool) -> Result<Vec<GridSpec>> {
        let windows = match &self.window {
            Some(w) => w.0.clone(),
            None if is_piv => PIV_WINDOWS.to_vec(),
            None => EVENT_WINDOWS.to_vec(),
        };
        let steps = match &self.step {
            Some(s) => s.0.clone(),
            None => windows
                .iter()
                .map(|&w| ((w as f64 * (1.0 - self.overlap)).round() as u32).max(1))
                .collect(),
        };
        if steps.len() != windows.len() {
            return Err(Error::parameter(
                "step",
                format!(
                    "{} steps for {} windows: give one step per pass",
                    steps.len(),
                    windows.len()
                ),
            ));
        }
        Ok(windows
            .iter()
            .zip(&steps)
            .map(|(&w, &s)| GridSpec {
                window: [w, w],
                step: [s, s],
                roi: self.roi,
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with(pairs: &[(&str, &str)]) -> Result<Resolved> {
        let mut s = ProcessSettings {
            input: Some("rec.raw".into()),
            ..ProcessSettings::default()
        };
        for (k, v) in pairs {
            s.set_flag(k, &[v.to_string()])?;
        }
        s.resolve()
    }

    #[test]
    fn defaults_follow_the_method() {
        let r = with(&[]).unwrap();
        let windows: Vec<u32> = r.process.passes.iter().map(|g| g.window[0]).collect();
        assert_eq!(windows, EVENT_WINDOWS);
        assert_eq!(r.process.passes[1].step, [20, 20]);
        assert_eq!(r.corrsum, CorrSumParams::default());
        assert_eq!(r.motion, MotionParams::default());
        let r = with(&[("method", "piv")]).unwrap();
        let windows: Vec<u32> = r.piv.passes.iter().map(|g| g.window[0]).collect();
        assert_eq!(windows, PIV_WINDOWS);
        assert_eq!(r.piv.predictor_smoothing, PIV_PREDICTOR_SMOOTHING);
        assert_eq!(r.process.predictor_smoothing, EVENT_PREDICTOR_SMOOTHING);
    }

    #[test]
    fn settings_are_checked_against_each_other() {
        let e = with(&[("window", "64,32"), ("step", "16")]).unwrap_err();
        assert!(e.to_string().contains("`step`"), "{e}");
        let e = with(&[("tau", "20ms")]).unwrap_err();
        assert!(e.to_string().contains("`tau`"), "{e}");
        let e = with(&[("origin", "1,2")]).unwrap_err();
        assert!(e.to_string().contains("`mm-per-px`"), "{e}");
        let e = with(&[("images", "a.png")]).unwrap_err();
        assert!(e.to_string().contains("`images`"), "{e}");
        // A method's own checks only apply to that method.
        assert!(with(&[("method", "piv"), ("tau", "20ms")]).is_ok());
    }

    #[test]
    fn an_auto_slab_resolves_its_bounds_and_checks_them() {
        let r = with(&[("slab", "auto"), ("slab-max", "100ms")]).unwrap();
        let adaptive = r.adaptive.unwrap();
        assert_eq!((adaptive.min_us, adaptive.max_us), (1_000, 100_000));
        assert_eq!(
            r.slab_us(),
            10_000,
            "the first pass's slab, and the field step"
        );
        assert!(with(&[("slab", "10ms")]).unwrap().adaptive.is_none());
        let e = with(&[("slab", "auto"), ("slab-probe", "1s")]).unwrap_err();
        assert!(e.to_string().contains("`slab-probe`"), "{e}");
    }

    #[test]
    fn one_fit_sets_every_estimator() {
        let r = with(&[("fit", "parabolic")]).unwrap();
        assert_eq!(r.corrsum.fit, crate::peak::SubPixelFit::Parabolic3);
        assert_eq!(r.motion.fit, r.corrsum.fit);
        assert_eq!(r.piv.fit, r.corrsum.fit);
    }
}
