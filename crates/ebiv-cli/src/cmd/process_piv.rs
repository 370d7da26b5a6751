//! `ebiv process --method piv|pulsed`: cross-correlation PIV of image pairs, of frames rebuilt
//! from an event recording, or of one frame per light pulse (pulsed EBIV).

use super::process_config::ProcessConfig;
use super::process_run::{
    describe_passes, finish_recording_run, load_mask, plan_fields, series_histograms,
    write_series_figures, FieldProgress, Method, Planned, Settings,
};
use crate::progress::count_bar;
use ebiv::estimate::peak::SubPixelFit;
use ebiv::field::{FieldSeries, Quantity};
use ebiv::frame::events::{FrameKind, FrameSpec};
use ebiv::frame::Frame;
use ebiv::grid::{Grid, GridSpec};
use ebiv::io::ReadOptions;
use ebiv::piv::{
    piv_ensemble, piv_events, CorrelationKind, DeformationMode, EventPivParams, FrameClock,
    Interpolation, PivParams,
};
use ebiv::render::{frame_image, save_png, vector_map, write_gif, VectorMapStyle};
use ebiv::validate::ValidationParams;
use ebiv::{Error, EventBuffer, PolaritySelection};
use std::path::Path;
use std::time::Instant;

/// Most memory the images of one run may take, bytes.
const MAX_IMAGE_MEMORY_BYTES: u64 = 8 << 30;
/// Events read at most to find the pulse timing.
const PULSE_SCAN_EVENTS: usize = 4_000_000;
/// Time read at most to find the pulse timing, µs.
const PULSE_SCAN_US: i64 = 2_000_000;

/// The PIV part of the settings, resolved.
#[derive(Debug, Clone)]
pub struct PivSettings {
    /// Engine settings (passes, correlation, deformation, validation, …).
    pub params: PivParams,
    /// How frames are rebuilt from events.
    pub frames: FrameSpec,
    /// Time between rebuilt frames, µs.
    pub frame_step_us: i64,
    /// Frame pairs per field (events).
    pub pairs: u32,
    /// Nominal pulse frequency (pulsed).
    pub pulse_hz: Option<f64>,
    /// Image files or patterns instead of a recording.
    pub images: Option<Vec<String>>,
    /// Images form a sequence (1,2), (2,3), … rather than pairs (1,2), (3,4), ….
    pub sequence: bool,
    /// Sum all image pairs into one field.
    pub ensemble: bool,
    /// Time between the frames of an image pair, µs (velocities instead of displacements).
    pub dt_us: Option<i64>,
}

/// Parse a named choice, or say which values are allowed.
fn choice<T>(
    key: &str,
    text: Option<&str>,
    parse: fn(&str) -> Option<T>,
    allowed: &str,
) -> Result<Option<T>, Error> {
    text.map(|t| parse(t).ok_or_else(|| Error::parameter(key, format!("`{t}` is not {allowed}"))))
        .transpose()
}

impl PivSettings {
    /// Resolve the PIV keys of a merged configuration.
    pub fn from_config(
        c: &ProcessConfig,
        passes: &[GridSpec],
        polarity: PolaritySelection,
        fit: Option<SubPixelFit>,
        validation: &ValidationParams,
    ) -> Result<PivSettings, Error> {
        let mut params = PivParams {
            passes: passes.to_vec(),
            validation: validation.clone(),
            replace_final: c.replace.unwrap_or(false),
            ..PivParams::default()
        };
        if let Some(fit) = fit {
            params.fit = fit;
        }
        if let Some(k) = choice(
            "correlation",
            c.correlation.as_deref(),
            CorrelationKind::parse,
            "circular or linear",
        )? {
            params.correlation = k;
        }
        if let Some(d) = choice(
            "deformation",
            c.deformation.as_deref(),
            DeformationMode::parse,
            "symmetric or second",
        )? {
            params.deformation = d;
        }
        if let Some(i) = choice(
            "interpolation",
            c.interpolation.as_deref(),
            Interpolation::parse,
            "quintic, cubic or linear",
        )? {
            params.interpolation = i;
        }
        if let Some(n) = c.iterations {
            params.final_iterations = n;
        }
        let kind = match c.frame_kind.as_deref() {
            Some(k) => FrameKind::parse(k)?,
            None => FrameKind::Count,
        };
        let frames = FrameSpec {
            kind,
            exposure_us: c.exposure.map(|d| d.0).unwrap_or(1500),
            polarity,
            splat_sigma: c.splat.unwrap_or(0.0),
        };
        frames.check()?;
        let frame_step_us = c.frame_step.map(|d| d.0).unwrap_or(2500);
        if frame_step_us <= 0 {
            return Err(Error::parameter("frame-step", "must be longer than 0"));
        }
        let pairs = c.pairs.unwrap_or(1);
        if pairs == 0 {
            return Err(Error::parameter(
                "pairs",
                "at least one frame pair per field",
            ));
        }
        if let Some(hz) = c.pulse_hz {
            if !(hz.is_finite() && hz > 0.0) {
                return Err(Error::parameter(
                    "pulse-hz",
                    format!("must be a positive frequency, got {hz}"),
                ));
            }
        }
        let dt_us = c.dt.map(|d| d.0);
        if dt_us.is_some_and(|d| d <= 0) {
            return Err(Error::parameter("dt", "must be longer than 0"));
        }
        params.check()?;
        Ok(PivSettings {
            params,
            frames,
            frame_step_us,
            pairs,
            pulse_hz: c.pulse_hz,
            images: c.images.clone(),
            sequence: c.sequence.unwrap_or(false),
            ensemble: c.ensemble.unwrap_or(false),
            dt_us,
        })
    }
}

/// PIV of image pairs given by `--images`.
pub fn run_images(s: &Settings) -> Result<(), Error> {
    let p = &s.piv;
    let paths = ebiv::frame::file::expand_image_list(p.images.as_deref().unwrap_or_default())?;
    if paths.len() < 2 {
        return Err(Error::parameter(
            "images",
            format!("PIV needs at least two images, got {}", paths.len()),
        ));
    }
    if !p.sequence && paths.len() % 2 != 0 {
        return Err(Error::parameter(
            "images",
            format!(
                "{} images do not form pairs (1,2), (3,4), …: give an even number, or --sequence for (1,2), (2,3), …",
                paths.len()
            ),
        ));
    }
    let bar = count_bar(paths.len() as u64, "images");
    let mut frames = Vec::with_capacity(paths.len());
    for path in &paths {
        let frame = ebiv::frame::file::load(path)?;
        // All images are held; an ensemble also holds resampling coefficients and deformed
        // copies of each.
        let per_image = frame.data.len() as u64 * 4 * if p.ensemble { 3 } else { 1 };
        if per_image * paths.len() as u64 > MAX_IMAGE_MEMORY_BYTES {
            return Err(Error::parameter(
                "images",
                format!(
                    "{} images of {}×{} px need about {} GiB; process fewer at a time",
                    paths.len(),
                    frame.width,
                    frame.height,
                    (per_image * paths.len() as u64) >> 30
                ),
            ));
        }
        frames.push(frame);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let g = frames[0].geometry();
    for (f, path) in frames.iter().zip(&paths) {
        if f.width != g.width || f.height != g.height {
            return Err(Error::parameter(
                "images",
                format!(
                    "{} is {}×{} px but {} is {g}: all images must have the same size",
                    path.display(),
                    f.width,
                    f.height,
                    paths[0].display()
                ),
            ));
        }
    }
    let pair_indices: Vec<(usize, usize)> = if p.sequence {
        (0..frames.len() - 1).map(|i| (i, i + 1)).collect()
    } else {
        (0..frames.len() / 2).map(|i| (2 * i, 2 * i + 1)).collect()
    };
    let mut params = p.params.clone();
    params.mask = load_mask(s, g)?;
    for pass in &params.passes {
        Grid::new(pass, g)?;
    }
    // Validation ε and limits are in px/ms when a dt is given, else in px.
    let dt_ms = p.dt_us.map(|d| d as f64 / 1000.0);
    if let Some(dt) = dt_ms {
        params = params.over_interval(dt);
    }
    let groups: Vec<Vec<(usize, usize)>> = if p.ensemble {
        vec![pair_indices.clone()]
    } else {
        pair_indices.iter().map(|&pair| vec![pair]).collect()
    };
    println!(
        "{} image(s) of {g} from {}: {} field(s) of {} pair(s) each, passes {}",
        paths.len(),
        paths[0]
            .parent()
            .map(Path::display)
            .map(|d| d.to_string())
            .unwrap_or_default(),
        groups.len(),
        groups[0].len(),
        describe(&params)
    );
    let bar = count_bar(groups.len() as u64, "fields");
    let started = Instant::now();
    let mut series: Option<FieldSeries> = None;
    let mut figures = Vec::new();
    let (mut valid, mut vectors, mut flagged) = (0usize, 0usize, 0usize);
    let quantity = if dt_ms.is_some() {
        Quantity::Velocity
    } else {
        Quantity::Displacement
    };
    if let Some(dir) = &s.png {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    for (k, group) in groups.iter().enumerate() {
        let pairs: Vec<(&Frame, &Frame)> = group
            .iter()
            .map(|&(a, b)| (&frames[a], &frames[b]))
            .collect();
        let out = piv_ensemble(&pairs, &params)?;
        let mut field = out.field;
        if let Some(dt) = dt_ms {
            field.scale(1.0 / dt);
        }
        vectors += field.len();
        valid += field.status.iter().filter(|s| s.is_valid()).count();
        flagged += out.validation.valid_before - out.validation.valid_after;
        let t = k as i64;
        let series =
            series.get_or_insert_with(|| FieldSeries::on_grid(field.x.clone(), field.y.clone()));
        series.push(t, &field)?;
        if let Some(dir) = &s.png {
            let (a, b) = group[0];
            let style = VectorMapStyle {
                title: Some(format!(
                    "{} / {}",
                    file_name(&paths[a]),
                    file_name(&paths[b])
                )),
                units: quantity.units().0.into(),
                ..VectorMapStyle::default()
            };
            let figure = vector_map(&field, g, Some(&frame_image(&frames[a])), &style);
            save_png(&figure, &dir.join(format!("field_{k:04}.png")))?;
            if figures.len() < 200 {
                figures.push(figure);
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let mut series = series.expect("at least one field");
    series.quantity = quantity;
    series.calibration = s.calibration;
    series.attributes = vec![
        (
            "software".into(),
            format!("ebiv {}", env!("CARGO_PKG_VERSION")),
        ),
        ("method".into(), "piv of image pairs".into()),
        (
            "source".into(),
            paths
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
        ),
        (
            "pairs".into(),
            pair_indices
                .iter()
                .map(|(a, b)| format!("({},{})", a + 1, b + 1))
                .collect::<Vec<_>>()
                .join(" "),
        ),
        ("ensemble".into(), p.ensemble.to_string()),
        (
            "field_time".into(),
            "index of the field (image pairs carry no time stamps)".into(),
        ),
    ];
    series.attributes.extend(ebiv::piv::attributes(&params));
    ebiv::export::write_field(&series, &s.output)?;
    println!(
        "{vectors} vectors in {} field(s), {:.1} % valid ({flagged} flagged by validation), in {seconds:.2} s",
        series.t_us.len(),
        100.0 * valid as f64 / vectors.max(1) as f64,
    );
    println!(
        "wrote {} ({} in {})",
        s.output.display(),
        quantity.noun(),
        quantity.units().0
    );
    if let Some(dir) = &s.png {
        let hist = series_histograms(&series, "", Some(dt_ms.unwrap_or(1.0)));
        save_png(&hist, &dir.join("histograms.png"))?;
        if figures.len() > 1 {
            write_gif(&figures, 200, &dir.join("animation.gif"))?;
        }
        println!(
            "figures in {}: histograms.png and {} vector map(s)",
            dir.display(),
            series.t_us.len()
        );
    }
    Ok(())
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned()
}

/// "64x64 px step 32 -> …, quintic symmetric deformation".
fn describe(p: &PivParams) -> String {
    let passes = ebiv::process::ProcessParams {
        passes: p.passes.clone(),
        ..Default::default()
    };
    format!(
        "{}, {:?} correlation, {:?} {:?} deformation",
        describe_passes(&passes),
        p.correlation,
        p.interpolation,
        p.deformation
    )
    .to_lowercase()
}

/// Find the pulse timing from up to 2 s of the recording (events of the selected polarity
/// and trigger edges), from the start of `--time` if given, else from the first event.
fn detect_pulse_timing(
    s: &Settings,
    options: &ReadOptions,
) -> Result<ebiv::frame::pulse::PulseTiming, Error> {
    let mut reader = ebiv::io::open(&s.input, options)?;
    if let Some(start) = s.time.0 {
        let origin = if s.absolute_time {
            0
        } else {
            super::first_event_time(&s.input, options)?.unwrap_or(0)
        };
        reader.skip_to(origin + start)?;
    }
    let mut batch = EventBuffer::new();
    let (mut times, mut triggers) = (Vec::new(), Vec::new());
    let mut first = None;
    'read: while reader.read_batch(&mut batch)? {
        triggers.extend_from_slice(&batch.triggers);
        for i in 0..batch.len() {
            let t = batch.t[i];
            let t_first = *first.get_or_insert(t);
            if t - t_first > PULSE_SCAN_US || times.len() >= PULSE_SCAN_EVENTS {
                break 'read;
            }
            if s.piv.frames.polarity.accepts(batch.p[i]) {
                times.push(t);
            }
        }
    }
    ebiv::frame::pulse::detect_pulses(&times, &triggers, s.piv.pulse_hz)
}

/// PIV of frames rebuilt from the recording (regular frames, or one per pulse).
pub fn run_events(s: &Settings, options: &ReadOptions) -> Result<(), Error> {
    let p = &s.piv;
    let clock = if s.method == Method::Pulsed {
        let timing = detect_pulse_timing(s, options)?;
        println!(
            "pulses: {:.3} Hz (period {:.3} µs), frames start {:.1} µs into each period, from {} ({} periods, modulation contrast {:.2})",
            timing.frequency_hz,
            timing.period_us,
            timing.phase_us(),
            match timing.source {
                ebiv::frame::pulse::PulseSource::Triggers => "trigger edges",
                ebiv::frame::pulse::PulseSource::EventHistogram => "the event rate",
            },
            timing.periods,
            timing.contrast
        );
        FrameClock::Pulsed(timing)
    } else {
        FrameClock::Regular {
            step_us: p.frame_step_us,
        }
    };
    let mut params = EventPivParams {
        frames: p.frames,
        clock,
        pairs: p.pairs,
        piv: p.params.clone(),
    };
    params.check()?;
    let (before, after) = params.time_extent_us();
    let Planned {
        mut reader,
        geometry: g,
        times,
    } = plan_fields(s, options, before, after, before + after)?;
    params.piv.mask = load_mask(s, g)?;
    for pass in &params.piv.passes {
        Grid::new(pass, g)?;
    }
    let plan = params.plan(times[0]);
    println!(
        "{}: {} field(s) from {} to {} µs, PIV of {} {} frames ({} µs exposure, Δt {:.1} µs, {} pair(s) per field) on {g}, passes {}",
        s.input.display(),
        times.len(),
        times[0],
        times[times.len() - 1],
        p.frames.kind.name(),
        format!("{:?}", p.frames.polarity).to_lowercase(),
        plan.exposure_us,
        plan.dt_us,
        p.pairs,
        describe(&params.piv)
    );
    if let Some(dir) = &s.png {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let started = Instant::now();
    let mut progress = FieldProgress::new(s, g, times.len(), (before, after));
    let (mut series, summary) = piv_events(&mut reader, g, &params, &times, &mut |d| {
        progress.on_field(d)
    })?;
    let figures = progress.finish()?;
    finish_recording_run(s, &mut series, &summary, started, &reader.report())?;
    if let Some(dir) = &s.png {
        write_series_figures(&series, dir, s, figures)?;
    }
    Ok(())
}
