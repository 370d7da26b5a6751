//! `ebiv process --method piv --images …`: cross-correlation PIV of image pairs. PIV of
//! frames rebuilt from a recording runs with the event methods ([`super::events`]).

use super::figures::{series_histograms, vector_style, MAX_GIF_FRAMES};
use crate::progress::count_bar;
use ebiv::field::Quantity;
use ebiv::piv::images::{image_folder, image_pairs, load_images, piv_image_series, scaled_params};
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
    let params = run.image_series_params(g)?;
    let (fields, per_field) = if run.ensemble {
        (1, pairs.len())
    } else {
        (pairs.len(), 1)
    };
    println!(
        "{} image(s) of {g} from {}: {fields} field(s) of {per_field} pair(s) each, passes {}",
        paths.len(),
        image_folder(&paths),
        ebiv::settings::describe_piv(&scaled_params(&params))
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
    run.finish_series(&mut series)?;
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
        let maps = super::figures::write_derived_maps(&series, dir, run)?
            .map(|m| format!(", {m}"))
            .unwrap_or_default();
        println!(
            "figures in {}: histograms.png and {} vector map(s){maps}",
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
