//! What `ebiv process` shows and writes besides the field file: the progress bar, a vector
//! map per field, histograms, the animation, and the summary lines.

use crate::progress::count_bar;
use ebiv::field::{FieldSeries, Quantity};
use ebiv::process::{FieldDone, Method, RunSummary};
use ebiv::render::{
    save_png, time_coded_image, valid_components, vector_map, velocity_histograms, write_gif,
    HistogramStyle, VectorMapStyle,
};
use ebiv::settings::Resolved;
use ebiv::{Error, Geometry};
use std::time::Instant;

/// At most this many frames go into the animation.
pub const MAX_GIF_FRAMES: usize = 200;

/// Progress bar and per-field figures of a run over a recording: one vector map per field
/// (`--png`), the first [`MAX_GIF_FRAMES`] kept for the animation.
pub struct FieldProgress<'a> {
    run: &'a Resolved,
    geometry: Geometry,
    extent_us: (i64, i64),
    bar: indicatif::ProgressBar,
    figures: Vec<image::RgbImage>,
}

impl<'a> FieldProgress<'a> {
    /// For `fields` fields whose events span `extent_us` around their times.
    pub fn new(
        run: &'a Resolved,
        geometry: Geometry,
        fields: usize,
        extent_us: (i64, i64),
    ) -> Self {
        FieldProgress {
            run,
            geometry,
            extent_us,
            bar: count_bar(fields as u64, "fields"),
            figures: Vec::new(),
        }
    }

    /// Advance the bar and draw the field; an error if its figure cannot be written. A field
    /// whose windows held no event is not drawn (it would be a blank figure; the run reports
    /// empty fields).
    pub fn on_field(&mut self, d: &FieldDone) -> Result<(), Error> {
        self.bar.set_position(d.done as u64);
        let Some(dir) = &self.run.png else {
            return Ok(());
        };
        if d.field.event_count.iter().all(|&n| n == 0) {
            return Ok(());
        }
        let figure = field_figure(d, self.geometry, self.run, self.extent_us);
        save_png(&figure, &dir.join(format!("field_{:04}.png", d.done - 1)))?;
        if self.figures.len() < MAX_GIF_FRAMES {
            self.figures.push(figure);
        }
        Ok(())
    }

    /// Clear the bar; the figures for the animation.
    pub fn finish(self) -> Vec<image::RgbImage> {
        self.bar.finish_and_clear();
        self.figures
    }
}

/// After a run over a recording: report dropped input, write the series and print the summary line (vectors, valid share, time, throughput).
pub fn finish_recording_run(
    run: &Resolved,
    series: &mut FieldSeries,
    summary: &RunSummary,
    started: Instant,
    report: &ebiv::io::DecodeReport,
) -> Result<(), Error> {
    let seconds = started.elapsed().as_secs_f64();
    crate::cmd::print_report_summary(report);
    ebiv::export::write_field(series, &run.output)?;
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
    print_invalid_flags(series);
    if summary.lone_pixel_events > 0 {
        println!(
            "{}",
            ebiv::process::lone_pixel_line(summary.lone_pixel_events)
        );
    }
    println!("wrote {}", run.output.display());
    Ok(())
}

/// "invalid: 6 median_test, 5 out_of_range": how many invalid vectors carry each status flag
/// (a vector may carry several), so that the valid share and the validation count add up.
pub fn print_invalid_flags(series: &FieldSeries) {
    let counts: Vec<String> = ebiv::field::Status::NAMES
        .iter()
        .filter_map(|&(name, flag)| {
            let n = series
                .status
                .iter()
                .filter(|s| !s.is_valid() && s.contains(flag))
                .count();
            (n > 0).then(|| format!("{n} {name}"))
        })
        .collect();
    if !counts.is_empty() {
        println!("invalid vectors by flag: {}", counts.join(", "));
    }
}

/// The style of the vector maps of a run: `title`, velocities or displacements in `units`,
/// and the run's `arrow-stride` (default: thinned to a readable density).
pub fn vector_style(run: &Resolved, title: String, units: &str) -> VectorMapStyle {
    VectorMapStyle {
        title: Some(title),
        units: units.into(),
        stride: run.arrow_stride.map(|s| s as usize),
        ..VectorMapStyle::default()
    }
}

/// The vector map of one field over the time-coded image of its slab.
fn field_figure(d: &FieldDone, g: Geometry, run: &Resolved, extent: (i64, i64)) -> image::RgbImage {
    let half = extent.0.min(extent.1).max(1);
    let events = time_coded_image(d.events, g, d.t0_us, half, run.process.polarity);
    let title = format!(
        "{} t = {:.2} ms",
        run.input_path()
            .file_name()
            .unwrap_or_default()
            .to_string_lossy(),
        d.t0_us as f64 / 1000.0
    );
    let style = vector_style(run, title, Quantity::Velocity.units().0);
    vector_map(d.field, g, Some(&events.image), &style)
}

/// Histograms of the valid u and v of a series, with the fractional displacement that
/// exposes peak locking (see [`histogram_style`]).
pub fn series_histograms(
    series: &FieldSeries,
    title_prefix: &str,
    tau_ms: Option<f64>,
) -> image::RgbImage {
    let (u, v) = valid_components(&series.u, &series.v, &series.status);
    let style = histogram_style(
        series.quantity,
        &format!("{title_prefix}{} valid vectors", u.len()),
        tau_ms,
    );
    velocity_histograms(&u, &v, &style)
}

/// How the histograms of a series of `quantity` are drawn: in its units (px/ms for
/// velocities, px for the displacements of image pairs without a time between frames),
/// with velocities turned into displacements over `tau_ms` for the fractional part, and
/// displacements taken as they are.
fn histogram_style(quantity: Quantity, title: &str, tau_ms: Option<f64>) -> HistogramStyle {
    HistogramStyle {
        displacement_ms: match quantity {
            Quantity::Velocity => tau_ms,
            Quantity::Displacement => None,
        },
        units: quantity.units().0.into(),
        title: Some(title.into()),
        ..HistogramStyle::default()
    }
}

/// Histograms of u and v and the animation, after the run.
pub fn write_series_figures(
    series: &FieldSeries,
    dir: &std::path::Path,
    run: &Resolved,
    frames: Vec<image::RgbImage>,
) -> Result<(), Error> {
    let tau_ms = match run.method {
        Method::CorrSum => Some(run.corrsum.tau_us as f64 / 1000.0),
        Method::Piv => Some(run.frame_step_us as f64 / 1000.0),
        Method::Motion | Method::Pulsed => None,
    };
    let hist = series_histograms(series, "", tau_ms);
    save_png(&hist, &dir.join("histograms.png"))?;
    let mut written = format!("histograms.png and {} vector map(s)", series.t_us.len());
    if frames.len() > 1 {
        write_gif(&frames, 200, &dir.join("animation.gif"))?;
        written.push_str(", animation.gif");
    }
    if let Some(maps) = write_derived_maps(series, dir, run)? {
        written.push_str(&format!(", {maps}"));
    }
    println!("figures in {}: {written}", dir.display());
    Ok(())
}

/// With `derive`: a colour map of the first derived quantity per field, vectors on top;
/// what was written, for the summary line.
pub fn write_derived_maps(
    series: &FieldSeries,
    dir: &std::path::Path,
    run: &Resolved,
) -> Result<Option<String>, Error> {
    let Some(&first) = run.derive.first() else {
        return Ok(None);
    };
    let quantity = ebiv::render::MapQuantity::Derived(first);
    let style = ebiv::render::FieldMapStyle {
        vectors: true,
        stride: run.arrow_stride.map(|s| s as usize),
        // One colour range for every map of the run, so that they compare.
        range: Some(ebiv::render::series_range(series, quantity)?),
        title: run
            .input_path()
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned(),
    };
    for t in 0..series.t_us.len() {
        let img = ebiv::render::field_map(series, t, quantity, &style)?;
        save_png(&img, &dir.join(format!("{}_{t:04}.png", first.name())))?;
    }
    Ok(Some(format!(
        "{} map(s) of {}",
        series.t_us.len(),
        first.name()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histograms_take_their_units_from_the_quantity() {
        let px = histogram_style(Quantity::Displacement, "pairs", Some(1.0));
        assert_eq!(px.units, "px");
        assert_eq!(
            px.displacement_ms, None,
            "displacements are not scaled by a time"
        );
        let v = histogram_style(Quantity::Velocity, "events", Some(2.0));
        assert_eq!((v.units.as_str(), v.displacement_ms), ("px/ms", Some(2.0)));
    }

    #[test]
    fn arrow_stride_reaches_the_vector_maps() {
        let mut settings = ebiv::settings::ProcessSettings {
            input: Some("rec.raw".into()),
            ..Default::default()
        };
        let run = settings.resolve().unwrap();
        assert_eq!(vector_style(&run, "t".into(), "px").stride, None);
        settings.set_flag("arrow-stride", &["1".into()]).unwrap();
        let run = settings.resolve().unwrap();
        let style = vector_style(&run, "t".into(), "px");
        assert_eq!((style.stride, style.units.as_str()), (Some(1), "px"));
        assert!(settings.set_flag("arrow-stride", &["0".into()]).is_err());
    }
}
