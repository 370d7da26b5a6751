//! Running `ebiv process`: resolve the settings, stream the recording through the chosen
//! estimator, write the field series and the figures, print the summary.

use super::process_config::ProcessConfig;
use crate::progress::count_bar;
use ebiv::estimate::corrsum::{CorrSumParams, SumOfCorrelation, Weighting};
use ebiv::estimate::motion::{ContrastMaximization, MotionParams, SearchMethod};
use ebiv::estimate::peak::SubPixelFit;
use ebiv::estimate::Estimator;
use ebiv::field::{Calibration, FieldSeries};
use ebiv::filter::Roi;
use ebiv::grid::{GridSpec, Mask};
use ebiv::io::ReadOptions;
use ebiv::process::{
    process_recording, scan_extent, FieldDone, ProcessParams, RunSummary, TimeSteps,
};
use ebiv::render::{
    save_png, time_coded_image, valid_components, vector_map, velocity_histograms, write_gif,
    HistogramStyle, VectorMapStyle,
};
use ebiv::{Error, Geometry, PolaritySelection};
use std::path::PathBuf;
use std::time::Instant;

/// At most this many frames go into the animation.
const MAX_GIF_FRAMES: usize = 200;

/// The estimators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    CorrSum,
    Motion,
    /// Cross-correlation PIV of image pairs or of frames rebuilt from events.
    Piv,
    /// PIV of one frame per light pulse.
    Pulsed,
}

/// Every setting of a run, resolved and checked.
#[derive(Debug, Clone)]
pub struct Settings {
    /// The recording; a placeholder naming the first image with `--images`.
    pub input: PathBuf,
    pub method: Method,
    /// PIV settings (methods piv and pulsed).
    pub piv: super::process_piv::PivSettings,
    pub corrsum: CorrSumParams,
    pub motion: MotionParams,
    pub params: ProcessParams,
    /// START, END (relative to the first event unless `absolute_time`) and STEP, µs.
    pub time: (Option<i64>, Option<i64>, Option<i64>),
    pub absolute_time: bool,
    pub output: PathBuf,
    pub png: Option<PathBuf>,
    pub calibration: Option<Calibration>,
    /// The mask image, loaded and checked against the sensor size when the run starts.
    pub mask: Option<PathBuf>,
}

impl Settings {
    /// Resolve a merged configuration into settings, with defaults and checks.
    pub fn from_config(c: &ProcessConfig) -> Result<Settings, Error> {
        let method = match c.method.as_deref().unwrap_or("corrsum") {
            "corrsum" | "sum-of-correlation" | "correlation" => Method::CorrSum,
            "motion" | "motion-compensation" | "cmax" => Method::Motion,
            "piv" => Method::Piv,
            "pulsed" | "pulsed-ebiv" => Method::Pulsed,
            other => {
                return Err(Error::parameter(
                    "method",
                    format!("`{other}` is not corrsum, motion, piv or pulsed"),
                ))
            }
        };
        let is_piv = matches!(method, Method::Piv | Method::Pulsed);
        if c.images.is_some() && method != Method::Piv {
            return Err(Error::parameter("images", "image input needs --method piv"));
        }
        let input = match (&c.input, &c.images) {
            (Some(_), Some(_)) => {
                return Err(Error::parameter(
                    "images",
                    "give either a recording or --images, not both",
                ))
            }
            (Some(i), None) => i.clone(),
            (None, Some(images)) => PathBuf::from(images.first().cloned().unwrap_or_default()),
            (None, None) => {
                return Err(Error::parameter(
                    "input",
                    "no recording given (ebiv process FILE, or `input` in the config)",
                ))
            }
        };
        let default_windows = if is_piv {
            vec![64, 32, 16]
        } else {
            vec![64, 40]
        };
        let windows = c
            .window
            .as_ref()
            .map(|w| w.values())
            .unwrap_or(default_windows);
        let overlap = c.overlap.unwrap_or(0.5);
        if !(0.0..1.0).contains(&overlap) {
            return Err(Error::parameter(
                "overlap",
                format!("must lie in [0, 1), got {overlap}"),
            ));
        }
        let steps = match &c.step {
            Some(s) => s.values(),
            None => windows
                .iter()
                .map(|&w| ((w as f64 * (1.0 - overlap)).round() as u32).max(1))
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
        let roi = c.roi.as_deref().map(Roi::parse).transpose()?;
        let passes = passes_for_piv(&windows, &steps, roi);
        let polarity = match c.polarity.as_deref() {
            None => PolaritySelection::Positive,
            Some(p) => PolaritySelection::parse(p).ok_or_else(|| {
                Error::parameter("polarity", format!("`{p}` is not pos, neg or both"))
            })?,
        };
        let fit = match c.fit.as_deref() {
            None => None,
            Some(f) => Some(SubPixelFit::parse(f).ok_or_else(|| {
                Error::parameter("fit", format!("`{f}` is not gauss3, parabolic or gauss2d"))
            })?),
        };
        let mut corrsum = c.corrsum.unwrap_or_default();
        let mut motion = c.motion.clone().unwrap_or_default();
        if let Some(slab) = c.slab {
            corrsum.slab_us = slab.0;
            motion.slab_us = slab.0;
        }
        if let Some(tau) = c.tau {
            corrsum.tau_us = tau.0;
        }
        if let Some(n) = c.slices {
            corrsum.slices = n;
        }
        if let Some(fit) = fit {
            corrsum.fit = fit;
            motion.fit = fit;
        }
        if let Some(search) = c.motion_search.as_deref() {
            motion.search = match search {
                "newton" => SearchMethod::Newton,
                "grid" => SearchMethod::Grid,
                other => {
                    return Err(Error::parameter(
                        "motion-search",
                        format!("`{other}` is not newton or grid"),
                    ))
                }
            };
        }
        if let Some(sigma) = c.peak_smoothing {
            corrsum.peak_smoothing_px = sigma;
        }
        if let Some(on) = c.subpixel_shift {
            corrsum.subpixel_shift = on;
        }
        if let Some(weighting) = c.weighting.as_deref() {
            corrsum.weighting = match weighting {
                "binary" => Weighting::Binary,
                "count" => Weighting::Count,
                other => {
                    return Err(Error::parameter(
                        "weighting",
                        format!("`{other}` is not binary or count"),
                    ))
                }
            };
        }
        if c.search_range.is_some() {
            motion.search_range = c.search_range;
        }
        corrsum.validate()?;
        motion.validate()?;
        let validation = c.validation.clone().unwrap_or_default();
        validation.check()?;
        let time = match &c.time {
            Some(t) => {
                let (s, e, step) = TimeSteps::parse(t)?;
                (s, e, Some(step))
            }
            None => (None, None, None),
        };
        let calibration = match c.mm_per_px {
            Some(mm_per_px) => {
                let cal = Calibration {
                    mm_per_px,
                    origin_px: c.origin.unwrap_or([0.0, 0.0]),
                    y_up: c.y_up.unwrap_or(false),
                };
                cal.validate()?;
                Some(cal)
            }
            None if c.origin.is_some() || c.y_up == Some(true) => {
                return Err(Error::parameter(
                    "mm-per-px",
                    "origin and y-up need a calibration scale (--mm-per-px)",
                ))
            }
            None => None,
        };
        let piv = super::process_piv::PivSettings::from_config(
            c,
            &passes_for_piv(&windows, &steps, roi),
            polarity,
            fit,
            &validation,
        )?;
        Ok(Settings {
            input,
            method,
            piv,
            corrsum,
            motion,
            params: ProcessParams {
                passes: passes.clone(),
                polarity,
                validation,
                replace_final: c.replace.unwrap_or(false),
                secondary_peaks: c.secondary_peaks.unwrap_or(true),
                ..ProcessParams::default()
            },
            time,
            absolute_time: c.absolute_time.unwrap_or(false),
            output: c.output.clone().unwrap_or_else(|| PathBuf::from("flow.nc")),
            png: c.png.clone(),
            calibration,
            mask: c.mask.clone(),
        })
    }

    /// Slab length T, µs (corrsum and motion).
    fn slab_us(&self) -> i64 {
        match self.method {
            Method::Motion => self.motion.slab_us,
            _ => self.corrsum.slab_us,
        }
    }
}

/// The grid specs of the passes.
fn passes_for_piv(windows: &[u32], steps: &[u32], roi: Option<Roi>) -> Vec<GridSpec> {
    windows
        .iter()
        .zip(steps)
        .map(|(&w, &s)| GridSpec {
            window: [w, w],
            step: [s, s],
            roi,
        })
        .collect()
}

/// Run the settings on their recording.
pub fn run_config(s: &Settings, options: &ReadOptions) -> Result<(), Error> {
    match s.method {
        Method::CorrSum => execute(s, options, &SumOfCorrelation::new(s.corrsum)?),
        Method::Motion => execute(s, options, &ContrastMaximization::new(s.motion.clone())?),
        Method::Piv if s.piv.images.is_some() => super::process_piv::run_images(s),
        Method::Piv | Method::Pulsed => super::process_piv::run_events(s, options),
    }
}

/// An opened recording with its sensor size and the field times of a run.
pub struct Planned {
    pub reader: ebiv::io::EventReader,
    pub geometry: Geometry,
    pub times: Vec<i64>,
}

/// Open the recording and resolve the field times: `--time` (relative to the first event
/// unless absolute), or every field that fits given the time a field needs `before` and
/// `after` its centre, one every `default_step` µs.
pub fn plan_fields(
    s: &Settings,
    options: &ReadOptions,
    before: i64,
    after: i64,
    default_step: i64,
) -> Result<Planned, Error> {
    let reader = ebiv::io::open(&s.input, options)?;
    let mut geometry = reader.metadata().geometry;
    let no_events = || Error::parameter("input", format!("{} holds no events", s.input.display()));
    let both_times = s.time.0.is_some() && s.time.1.is_some();
    // The whole recording is read only for what its header does not say: the sensor size or
    // where the fields that fit begin and end. Given `--time START:END`, relative times
    // need only the first event (in file order, the origin of every command's relative
    // times).
    let extent = if geometry.is_none() || !both_times {
        let mut scan = ebiv::io::open(&s.input, options)?;
        scan_extent(&mut scan)?.ok_or_else(no_events)?
    } else {
        let first_us = if s.absolute_time {
            0
        } else {
            super::first_event_time(&s.input, options)?.ok_or_else(no_events)?
        };
        ebiv::process::RecordingExtent {
            first_in_file_us: first_us,
            first_us,
            last_us: first_us,
            max_x: 0,
            max_y: 0,
            events: 0,
        }
    };
    let g = *geometry.get_or_insert(Geometry::new(
        extent.max_x as u32 + 1,
        extent.max_y as u32 + 1,
    ));
    let origin = if s.absolute_time {
        0
    } else {
        extent.first_in_file_us
    };
    let step = s.time.2.unwrap_or(default_step);
    let fitting = TimeSteps::fitting(extent.first_us, extent.last_us, before, after, step);
    let start = s.time.0.map(|t| origin + t);
    let end = s.time.1.map(|t| origin + t);
    let steps = match (start, end, fitting) {
        (Some(a), Some(b), _) => TimeSteps { start: a, end: b, step },
        (a, b, Some(f)) => TimeSteps {
            start: a.unwrap_or(f.start),
            end: b.unwrap_or(f.end),
            step,
        },
        _ => {
            return Err(Error::parameter(
                "time",
                format!(
                    "the recording ({} ms) is shorter than one field needs ({} ms); use a shorter --slab (piv: --frame-step, --exposure, --pairs)",
                    (extent.last_us - extent.first_us) / 1000,
                    (before + after) / 1000
                ),
            ))
        }
    };
    let times = steps.times(1_000_000)?;
    Ok(Planned {
        reader,
        geometry: g,
        times,
    })
}

/// Load the mask image, if any, and check it against the sensor.
pub fn load_mask(s: &Settings, g: Geometry) -> Result<Option<Mask>, Error> {
    let Some(path) = &s.mask else {
        return Ok(None);
    };
    let image = ebiv::frame::file::load(path)?;
    if image.width != g.width || image.height != g.height {
        return Err(Error::parameter(
            "mask",
            format!(
                "{} is {}×{} px but the sensor is {g}",
                path.display(),
                image.width,
                image.height
            ),
        ));
    }
    Ok(Some(Mask {
        width: image.width,
        height: image.height,
        masked: image.data.iter().map(|&v| v != 0.0).collect(),
    }))
}

fn execute<E: Estimator>(s: &Settings, options: &ReadOptions, estimator: &E) -> Result<(), Error> {
    let (before, after) = estimator.time_extent_us();
    let Planned {
        mut reader,
        geometry: g,
        times,
    } = plan_fields(s, options, before, after, s.slab_us())?;
    let mut params = s.params.clone();
    params.mask = load_mask(s, g)?;
    params.grids(g)?; // report a window that does not fit before anything else
    println!(
        "{}: {} field(s) from {} to {} µs, {} on {g}, passes {}",
        s.input.display(),
        times.len(),
        times[0],
        times[times.len() - 1],
        estimator.name(),
        describe_passes(&s.params)
    );
    if let Some(dir) = &s.png {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let started = Instant::now();
    let mut progress = FieldProgress::new(s, g, times.len(), estimator.time_extent_us());
    let (mut series, summary) =
        process_recording(&mut reader, g, estimator, &params, &times, &mut |d| {
            progress.on_field(d)
        })?;
    let frames = progress.finish()?;
    finish_recording_run(s, &mut series, &summary, started, &reader.report())?;
    if let Some(dir) = &s.png {
        write_series_figures(&series, dir, s, frames)?;
    }
    Ok(())
}

/// Progress bar and per-field figures of a run over a recording: one vector map per field
/// (`--png`), the first [`MAX_GIF_FRAMES`] kept for the animation.
pub struct FieldProgress<'a> {
    settings: &'a Settings,
    geometry: Geometry,
    extent_us: (i64, i64),
    bar: indicatif::ProgressBar,
    figures: Vec<image::RgbImage>,
    error: Option<Error>,
}

impl<'a> FieldProgress<'a> {
    /// For `fields` fields whose events span `extent_us` around their times.
    pub fn new(
        settings: &'a Settings,
        geometry: Geometry,
        fields: usize,
        extent_us: (i64, i64),
    ) -> Self {
        FieldProgress {
            settings,
            geometry,
            extent_us,
            bar: count_bar(fields as u64, "fields"),
            figures: Vec::new(),
            error: None,
        }
    }

    /// Advance the bar and draw the field (the first failure to write stops the drawing).
    pub fn on_field(&mut self, d: &FieldDone) {
        self.bar.set_position(d.done as u64);
        if let (Some(dir), None) = (&self.settings.png, &self.error) {
            let figure = field_figure(d, self.geometry, self.settings, self.extent_us);
            let path = dir.join(format!("field_{:04}.png", d.done - 1));
            if let Err(e) = save_png(&figure, &path) {
                self.error = Some(e);
            } else if self.figures.len() < MAX_GIF_FRAMES {
                self.figures.push(figure);
            }
        }
    }

    /// Clear the bar; the figures for the animation, or the first error.
    pub fn finish(self) -> Result<Vec<image::RgbImage>, Error> {
        self.bar.finish_and_clear();
        match self.error {
            Some(e) => Err(e),
            None => Ok(self.figures),
        }
    }
}

/// After a run over a recording: report dropped input, attach calibration and source,
/// write the series and print the summary line (vectors, valid share, time, throughput).
pub fn finish_recording_run(
    s: &Settings,
    series: &mut FieldSeries,
    summary: &RunSummary,
    started: Instant,
    report: &ebiv::io::DecodeReport,
) -> Result<(), Error> {
    let seconds = started.elapsed().as_secs_f64();
    super::print_report_summary(report);
    series.calibration = s.calibration;
    series
        .attributes
        .push(("source".into(), s.input.display().to_string()));
    ebiv::export::write_field(series, &s.output)?;
    let secondary = match summary.secondary_peaks {
        0 => String::new(),
        n => format!("; {n} outliers valid on a secondary peak"),
    };
    println!(
        "{} vectors in {} field(s), {:.1} % valid ({} flagged by validation{secondary}), in {:.2} s ({:.1} M events/s read, {:.0} vectors/s)",
        summary.vectors,
        summary.fields,
        100.0 * summary.valid as f64 / summary.vectors.max(1) as f64,
        summary.flagged,
        seconds,
        summary.events_read as f64 / seconds / 1e6,
        summary.vectors as f64 / seconds
    );
    println!("wrote {}", s.output.display());
    Ok(())
}

/// "64×64/32 → 40×40/20".
pub fn describe_passes(p: &ProcessParams) -> String {
    p.passes
        .iter()
        .map(|g| format!("{}x{} px step {}", g.window[0], g.window[1], g.step[0]))
        .collect::<Vec<_>>()
        .join(" -> ")
}

/// The vector map of one field over the time-coded image of its slab.
pub fn field_figure(
    d: &FieldDone,
    g: Geometry,
    s: &Settings,
    extent: (i64, i64),
) -> image::RgbImage {
    let half = extent.0.min(extent.1).max(1);
    let events = time_coded_image(d.events, g, d.t0_us, half, s.params.polarity);
    let style = VectorMapStyle {
        title: Some(format!(
            "{} t = {:.2} ms",
            s.input.file_name().unwrap_or_default().to_string_lossy(),
            d.t0_us as f64 / 1000.0
        )),
        ..VectorMapStyle::default()
    };
    vector_map(d.field, g, Some(&events.image), &style)
}

/// Histograms of the valid u and v of a series (with the fractional displacement over
/// `tau_ms`, when given, to expose peak locking).
pub fn series_histograms(
    series: &FieldSeries,
    title_prefix: &str,
    tau_ms: Option<f64>,
) -> image::RgbImage {
    let (u, v) = valid_components(&series.u, &series.v, &series.status);
    velocity_histograms(
        &u,
        &v,
        &HistogramStyle {
            displacement_ms: tau_ms,
            title: Some(format!("{title_prefix}{} valid vectors", u.len())),
            ..HistogramStyle::default()
        },
    )
}

/// Histograms of u and v and the animation, after the run.
pub fn write_series_figures(
    series: &FieldSeries,
    dir: &std::path::Path,
    s: &Settings,
    frames: Vec<image::RgbImage>,
) -> Result<(), Error> {
    let tau_ms = match s.method {
        Method::CorrSum => Some(s.corrsum.tau_us as f64 / 1000.0),
        Method::Piv => Some(s.piv.frame_step_us as f64 / 1000.0),
        Method::Motion | Method::Pulsed => None,
    };
    let hist = series_histograms(series, "", tau_ms);
    save_png(&hist, &dir.join("histograms.png"))?;
    let mut written = format!("histograms.png and {} vector map(s)", series.t_us.len());
    if frames.len() > 1 {
        write_gif(&frames, 200, &dir.join("animation.gif"))?;
        written.push_str(", animation.gif");
    }
    println!("figures in {}: {written}", dir.display());
    Ok(())
}
