//! `ebiv process --method piv|pulsed`: cross-correlation PIV of image pairs, of frames rebuilt
//! from an event recording, or of one frame per light pulse (pulsed EBIV).

use super::figures::{
    describe_passes, finish_recording_run, series_histograms, vector_style, write_series_figures,
    FieldProgress, MAX_GIF_FRAMES,
};
use crate::progress::count_bar;
use ebiv::field::Quantity;
use ebiv::frame::pulse::PulseSource;
use ebiv::io::ReadOptions;
use ebiv::piv::images::{
    image_folder, image_pairs, load_images, piv_image_series, scaled_params, ImageSeriesParams,
};
use ebiv::piv::{piv_events, EventPivParams, FrameClock, PivParams};
use ebiv::process::{first_event_time, Method, PlannedFields};
use ebiv::render::{frame_image, save_png, vector_map, write_gif};
use ebiv::settings::{Resolved, Source};
use ebiv::Error;
use std::path::Path;
use std::time::Instant;

/// PIV of image pairs given by `--images`.
pub fn run_images(run: &Resolved) -> Result<(), Error> {
    let Source::Images(patterns) = &run.source else {
        unreachable!("called for image input only")
    };
    let paths = ebiv::frame::file::expand_image_list(patterns)?;
    let pairs = image_pairs(paths.len(), run.sequence)?; // before loading anything
    let bar = count_bar(paths.len() as u64, "images");
    let frames = load_images(&paths, run.ensemble, &mut || bar.inc(1))?;
    bar.finish_and_clear();
    crate::interrupt::check(&run.output)?;
    let g = frames[0].geometry();
    let mut params = ImageSeriesParams {
        piv: run.piv.clone(),
        sequence: run.sequence,
        ensemble: run.ensemble,
        dt_us: run.dt_us,
    };
    params.piv.mask = run.mask_for(g)?;
    for pass in &params.piv.passes {
        ebiv::grid::Grid::new(pass, g)?;
    }
    let (fields, per_field) = if run.ensemble {
        (1, pairs.len())
    } else {
        (pairs.len(), 1)
    };
    println!(
        "{} image(s) of {g} from {}: {fields} field(s) of {per_field} pair(s) each, passes {}",
        paths.len(),
        image_folder(&paths),
        describe(&scaled_params(&params))
    );
    let quantity = if run.dt_us.is_some() {
        Quantity::Velocity
    } else {
        Quantity::Displacement
    };
    if let Some(dir) = &run.png {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let bar = count_bar(fields as u64, "fields");
    let started = Instant::now();
    let mut figures = Vec::new();
    let (mut series, summary) = piv_image_series(&frames, &paths, &params, &mut |done| {
        bar.inc(1);
        if done.index + 1 < fields {
            crate::interrupt::check(&run.output)?;
        }
        let Some(dir) = &run.png else {
            return Ok(());
        };
        let (a, b) = done.pairs[0];
        let title = format!("{} / {}", file_name(&paths[a]), file_name(&paths[b]));
        let style = vector_style(run, title, quantity.units().0);
        let figure = vector_map(done.field, g, Some(&frame_image(&frames[a])), &style);
        save_png(&figure, &dir.join(format!("field_{:04}.png", done.index)))?;
        if figures.len() < MAX_GIF_FRAMES {
            figures.push(figure);
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    series.calibration = run.calibration;
    ebiv::export::write_field(&series, &run.output)?;
    println!(
        "{} vectors in {} field(s), {:.1} % valid ({} flagged by validation), in {seconds:.2} s",
        summary.vectors,
        series.t_us.len(),
        100.0 * summary.valid as f64 / summary.vectors.max(1) as f64,
        summary.flagged,
    );
    super::figures::print_invalid_flags(&series);
    println!(
        "wrote {} ({} in {})",
        run.output.display(),
        quantity.noun(),
        quantity.units().0
    );
    if let Some(dir) = &run.png {
        let dt_ms = run.dt_us.map(|d| d as f64 / 1000.0);
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
    format!(
        "{}, {:?} correlation, {:?} {:?} deformation",
        describe_passes(&p.passes),
        p.correlation,
        p.interpolation,
        p.deformation
    )
    .to_lowercase()
}

/// Find the pulse timing from the start of `--time` if given, else from the first event,
/// and say what was found.
fn detect_pulse_timing(
    run: &Resolved,
    options: &ReadOptions,
) -> Result<ebiv::frame::pulse::PulseTiming, Error> {
    let input = run.input_path();
    let mut reader = ebiv::io::open(&input, options)?;
    let start = match run.time.and_then(|t| t.start) {
        Some(start) if run.absolute_time => Some(start),
        Some(start) => Some(first_event_time(&input, options)?.unwrap_or(0) + start),
        None => None,
    };
    let timing = ebiv::frame::scan_pulse_timing(
        &mut reader,
        run.frames.polarity,
        start,
        None,
        run.pulse_hz,
    )?;
    println!(
        "pulses: {:.3} Hz (period {:.3} µs), frames start {:.1} µs into each period, from {} ({} periods, modulation contrast {:.2})",
        timing.frequency_hz,
        timing.period_us,
        timing.phase_us(),
        match timing.source {
            PulseSource::Triggers => "trigger edges",
            PulseSource::EventHistogram => "the event rate",
        },
        timing.periods,
        timing.contrast
    );
    Ok(timing)
}

/// PIV of frames rebuilt from the recording (regular frames, or one per pulse).
pub fn run_events(run: &Resolved, options: &ReadOptions) -> Result<(), Error> {
    let clock = if run.method == Method::Pulsed {
        FrameClock::Pulsed(detect_pulse_timing(run, options)?)
    } else {
        FrameClock::Regular {
            step_us: run.frame_step_us,
        }
    };
    let mut params = EventPivParams {
        frames: run.frames,
        clock,
        pairs: run.pairs,
        piv: run.piv.clone(),
    };
    params.check()?;
    let input = run.input_path();
    let (before, after) = params.time_extent_us();
    let planned = run.plan_fields(options, (before, after), before + after)?;
    crate::interrupt::check(&run.output)?;
    let described = planned.describe_times();
    let PlannedFields {
        mut reader,
        geometry: g,
        times,
        time_origin_us,
    } = planned;
    params.piv.mask = run.mask_for(g)?;
    for pass in &params.piv.passes {
        ebiv::grid::Grid::new(pass, g)?;
    }
    let plan = params.plan(times[0]);
    println!(
        "{}: {described}, PIV of {} {} frames ({} µs exposure, Δt {:.1} µs, {} pair(s) per field) on {g}, passes {}",
        input.display(),
        run.frames.kind.name(),
        format!("{:?}", run.frames.polarity).to_lowercase(),
        plan.exposure_us,
        plan.dt_us,
        run.pairs,
        describe(&params.piv)
    );
    if let Some(dir) = &run.png {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let started = Instant::now();
    let mut progress = FieldProgress::new(run, g, times.len(), (before, after));
    let (mut series, summary) = piv_events(&mut reader, g, &params, &times, &mut |d| {
        progress.on_field(d)?;
        if d.done < d.total {
            crate::interrupt::check(&run.output)?;
        }
        Ok(())
    })?;
    let figures = progress.finish();
    super::check_run_found_events(run, &summary, &described, run.frames.polarity)?;
    series.time_origin_us = Some(time_origin_us);
    finish_recording_run(run, &mut series, &summary, started, &reader.report())?;
    if let Some(dir) = &run.png {
        write_series_figures(&series, dir, run, figures)?;
    }
    Ok(())
}
