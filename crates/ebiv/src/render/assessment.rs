//! The figures of an assessment report (`ebiv assess -o DIR`) and the writing of the whole
//! report folder: JSON, tidy CSV, Markdown page and PNG figures
//! ([`crate::assess::report`] names them).

use super::axes::{ColourBar, ImageFigure};
use super::colormap::inferno;
use super::draw::{fill_rect, Rect};
use super::plot::{data_range, figure, Layer, Panel, BLUE, GREY, ORANGE, RED};
use crate::assess::report::{self, figures, ReportContext};
use crate::assess::{Agreement, Assessment, Coverage, ErrorBin, ErrorMap, FractionalHistogram};
use crate::error::{Error, Result};
use image::RgbImage;
use std::path::{Path, PathBuf};

/// The mean end-point error per grid node as a colour map over the sensor (inferno, from 0
/// to the largest node mean); nodes without a compared vector stay grey.
pub fn error_map_figure(map: &ErrorMap, unit: &str) -> RgbImage {
    let half = |axis: &[f64]| {
        if axis.len() > 1 {
            (axis[1] - axis[0]).abs() / 2.0
        } else {
            8.0
        }
    };
    let (hx, hy) = (half(&map.x), half(&map.y));
    let last = |axis: &[f64]| axis.last().copied().unwrap_or(0.0);
    let extent = (
        (last(&map.x) + hx + 0.5).max(1.0),
        (last(&map.y) + hy + 0.5).max(1.0),
    );
    let k = (640.0 / extent.0).clamp(0.25, 8.0);
    let top = map
        .mean_error
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let top = if top > 0.0 { top } else { 1.0 };
    let bar = ColourBar::linear((0.0, top), format!("mean |e| [{unit}]"), inferno);
    let nodes = map.count.iter().filter(|&&c| c > 0).count();
    let notes = vec![format!(
        "{nodes} of {} nodes with compared vectors. grey: none",
        map.count.len()
    )];
    let (fig, mut img) = ImageFigure::new(
        extent,
        (extent.0 * k, extent.1 * k),
        Some("Mean end-point error per node".into()),
        Some(bar),
        notes,
    );
    let a = fig.axes;
    fill_rect(&mut img, a.area, [235, 235, 235]);
    for (row, &y) in map.y.iter().enumerate() {
        for (col, &x) in map.x.iter().enumerate() {
            let i = row * map.x.len() + col;
            let colour = if map.count[i] > 0 && map.mean_error[i].is_finite() {
                inferno((map.mean_error[i] / top) as f32)
            } else {
                [160, 160, 160]
            };
            let (x0, x1) = (a.px(x - hx).round(), a.px(x + hx).round());
            let (y0, y1) = (a.py(y - hy).round(), a.py(y + hy).round());
            let r = Rect::new(x0.max(a.area.x0), y0.max(a.area.y0), 0.0, 0.0);
            let r = Rect {
                x1: x1.min(a.area.x1),
                y1: y1.min(a.area.y1),
                ..r
            };
            fill_rect(&mut img, r, colour);
        }
    }
    fig.decorate(&mut img);
    img
}

/// Mean and RMS end-point error in bins of a quantity (true speed, events per window).
pub fn error_bins_figure(bins: &[ErrorBin], x_label: &str, heading: &str, unit: &str) -> RgbImage {
    let centre = |b: &ErrorBin| 0.5 * (b.lo + b.hi);
    let aee: Vec<(f64, f64)> = bins.iter().map(|b| (centre(b), b.aee)).collect();
    let rms: Vec<(f64, f64)> = bins.iter().map(|b| (centre(b), b.rms)).collect();
    let x_range = data_range(bins.iter().flat_map(|b| [b.lo, b.hi]), (0.0, 1.0));
    let top = data_range(bins.iter().map(|b| b.rms), (0.0, 1.0)).1;
    let counts: Vec<String> = bins.iter().map(|b| b.count.to_string()).collect();
    let panel = Panel {
        heading: heading.into(),
        x_label: x_label.into(),
        y_label: format!("end-point error [{unit}]"),
        x_range,
        y_range: (0.0, top.max(1e-9) * 1.15),
        layers: vec![
            Layer::Line {
                points: rms,
                colour: ORANGE,
                markers: true,
            },
            Layer::Line {
                points: aee,
                colour: BLUE,
                markers: true,
            },
        ],
        notes: vec![
            (Some(BLUE), "mean |e| (AEE)".into()),
            (Some(ORANGE), "RMS |e|".into()),
        ],
    };
    figure(
        &[panel],
        None,
        &[format!("vectors per bin: {}", counts.join(" "))],
    )
}

/// Standard normal density.
fn normal(z: f64) -> f64 {
    (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// Left: histogram of e/σ as a density against the standard normal density; right: |e|
/// against σ with the lines |e| = σ and |e| = 2σ.
pub fn coverage_figure(c: &Coverage, unit: &str) -> RgbImage {
    let bins = c.normalised_histogram.len().max(1);
    let range = 4.0;
    let width = 2.0 * range / bins as f64;
    let total = c.samples.max(1) as f64;
    let edges: Vec<f64> = (0..=bins).map(|b| -range + b as f64 * width).collect();
    let density: Vec<f64> = c
        .normalised_histogram
        .iter()
        .map(|&n| n as f64 / total / width)
        .collect();
    let curve: Vec<(f64, f64)> = (0..=160)
        .map(|i| {
            let z = -range + i as f64 * 2.0 * range / 160.0;
            (z, normal(z))
        })
        .collect();
    let top = density.iter().copied().fold(normal(0.0), f64::max) * 1.15;
    let left = Panel {
        heading: "e / sigma, both components".into(),
        x_label: "e / sigma".into(),
        y_label: "density".into(),
        x_range: (-range, range),
        y_range: (0.0, top),
        layers: vec![
            Layer::Bars {
                edges,
                heights: density,
                colour: BLUE,
            },
            Layer::Line {
                points: curve,
                colour: RED,
                markers: false,
            },
        ],
        notes: vec![
            (
                None,
                format!("within ±1: {:.1} %", 100.0 * c.within_1_sigma),
            ),
            (
                None,
                format!("within ±2: {:.1} %", 100.0 * c.within_2_sigma),
            ),
            (Some(RED), "standard normal".into()),
        ],
    };
    let s_max = data_range(c.scatter.iter().map(|p| p[0]), (0.0, 1.0)).1;
    let e_max = data_range(c.scatter.iter().map(|p| p[1]), (0.0, 1.0)).1;
    let right = Panel {
        heading: "|e| against sigma".into(),
        x_label: format!("sigma [{unit}]"),
        y_label: format!("|e| [{unit}]"),
        x_range: (0.0, s_max.max(1e-9)),
        y_range: (0.0, e_max.max(1e-9)),
        layers: vec![
            Layer::Points {
                points: c.scatter.iter().map(|p| (p[0], p[1])).collect(),
                colour: BLUE,
            },
            Layer::Dashed {
                from: (0.0, 0.0),
                to: (s_max, s_max),
                colour: GREY,
            },
            Layer::Dashed {
                from: (0.0, 0.0),
                to: (s_max, 2.0 * s_max),
                colour: RED,
            },
        ],
        notes: vec![
            (None, format!("Spearman {:.2}", c.spearman)),
            (Some(GREY), "|e| = sigma".into()),
            (Some(RED), "|e| = 2sigma".into()),
        ],
    };
    figure(
        &[left, right],
        Some("Coverage of the per-vector uncertainty"),
        &[
            format!(
                "{} component errors with an uncertainty ({} without).",
                c.samples, c.without_uncertainty
            ),
            "Well-estimated sigma: bars follow the curve, 68.3 % within ±1, 95.4 % within ±2."
                .into(),
        ],
    )
}

/// The fractional-displacement histogram with the uniform level and the peak-locking index.
pub fn fractional_figure(f: &FractionalHistogram) -> RgbImage {
    let bins = f.counts.len().max(1);
    let edges: Vec<f64> = (0..=bins).map(|b| f.edge(b)).collect();
    let heights: Vec<f64> = f.counts.iter().map(|&c| c as f64).collect();
    let uniform = f.samples as f64 / bins as f64;
    let top = heights.iter().copied().fold(1.0, f64::max) * 1.3;
    let panel = Panel {
        heading: "fractional displacement".into(),
        x_label: "d - round(d) [px]".into(),
        y_label: "count".into(),
        x_range: (-0.5, 0.5),
        y_range: (0.0, top),
        layers: vec![
            Layer::Bars {
                edges,
                heights,
                colour: BLUE,
            },
            Layer::Dashed {
                from: (-0.5, uniform),
                to: (0.5, uniform),
                colour: RED,
            },
        ],
        notes: vec![
            (None, format!("n = {}", f.samples)),
            (None, format!("index = {:.2}", f.peak_locking_index)),
            (Some(RED), "uniform".into()),
        ],
    };
    figure(
        &[panel],
        None,
        &[
            "Peak-locking index 1 - lowest/tallest bar (Christensen 2004): 0 flat, 1 all at whole pixels."
                .into(),
            format!(
                "Noise alone gives about {:.2} here (3·sqrt(bins/n)). Far above that, with a peak at 0: peak locking.",
                f.noise_level
            ),
        ],
    )
}

/// u_a against u_b and v_a against v_b, with the diagonal.
pub fn scatter_figure(g: &Agreement) -> RgbImage {
    let panel = |k: usize, name: &str| {
        let pts: Vec<(f64, f64)> = g
            .scatter
            .iter()
            .map(|p| (p[k + 2] as f64, p[k] as f64))
            .collect();
        let r = data_range(pts.iter().flat_map(|p| [p.0, p.1]), (-1.0, 1.0));
        Panel {
            heading: format!("{name} component"),
            x_label: format!("{name} of b [{}]", g.unit),
            y_label: format!("{name} of a [{}]", g.unit),
            x_range: r,
            y_range: r,
            layers: vec![
                Layer::Points {
                    points: pts,
                    colour: BLUE,
                },
                Layer::Dashed {
                    from: (r.0, r.0),
                    to: (r.1, r.1),
                    colour: RED,
                },
            ],
            notes: vec![(None, format!("n = {}", g.scatter.len()))],
        }
    };
    figure(
        &[panel(0, "u"), panel(1, "v")],
        Some("a against b"),
        &["Points on the dashed diagonal agree.".into()],
    )
}

/// Histogram of |Δv| with the median and the threshold.
pub fn differences_figure(g: &Agreement) -> RgbImage {
    let mut sorted: Vec<f64> = g
        .differences
        .iter()
        .map(|&d| d as f64)
        .filter(|d| d.is_finite())
        .collect();
    sorted.sort_by(f64::total_cmp);
    let hi = sorted
        .get(((sorted.len() as f64) * 0.99) as usize)
        .or(sorted.last())
        .copied()
        .unwrap_or(1.0)
        .max(g.threshold * 1.2)
        .max(1e-9);
    let bins = 40;
    let mut counts = vec![0.0; bins];
    let mut outside = 0;
    for &d in &sorted {
        if d > hi {
            outside += 1;
        } else {
            counts[((d / hi * bins as f64) as usize).min(bins - 1)] += 1.0;
        }
    }
    let edges: Vec<f64> = (0..=bins).map(|b| b as f64 * hi / bins as f64).collect();
    let top = counts.iter().copied().fold(1.0, f64::max) * 1.2;
    let panel = Panel {
        heading: "|dv| = |v_a - v_b|".into(),
        x_label: format!("|dv| [{}]", g.unit),
        y_label: "count".into(),
        x_range: (0.0, hi),
        y_range: (0.0, top),
        layers: vec![
            Layer::Bars {
                edges,
                heights: counts,
                colour: BLUE,
            },
            Layer::Dashed {
                from: (g.median_difference, 0.0),
                to: (g.median_difference, top),
                colour: ORANGE,
            },
            Layer::Dashed {
                from: (g.threshold, 0.0),
                to: (g.threshold, top),
                colour: RED,
            },
        ],
        notes: vec![
            (Some(ORANGE), format!("median {:.3}", g.median_difference)),
            (
                Some(RED),
                format!(
                    "threshold {}: {:.1} % beyond",
                    g.threshold,
                    100.0 * g.beyond_share
                ),
            ),
            (None, format!("{outside} beyond the plot")),
        ],
    };
    figure(&[panel], None, &[])
}

/// Create `dir` if needed and check it is a folder.
fn prepare(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    if !dir.is_dir() {
        return Err(Error::Write {
            what: dir.display().to_string(),
            message: "not a folder".into(),
        });
    }
    Ok(())
}

/// Write the report of an assessment into `dir` (created if missing): `assessment.json`,
/// `assessment.csv`, `report.md` and its PNG figures. Returns the files written.
pub fn write_assessment_report(
    dir: &Path,
    a: &Assessment,
    context: &ReportContext,
) -> Result<Vec<PathBuf>> {
    prepare(dir)?;
    let mut written = Vec::new();
    let mut text = |name: &str, body: String| -> Result<()> {
        let p = dir.join(name);
        crate::export::write_text(&p, &body)?;
        written.push(p);
        Ok(())
    };
    text("assessment.json", report::assessment_json(a, context))?;
    text("assessment.csv", report::assessment_csv(a))?;
    text("report.md", report::assessment_markdown(a, context))?;
    let mut images = vec![
        (figures::ERROR_MAP, error_map_figure(&a.error_map, &a.unit)),
        (
            figures::ERROR_VS_SPEED,
            error_bins_figure(
                &a.by_speed,
                &format!("true speed [{}]", a.unit),
                "Error against the true speed",
                &a.unit,
            ),
        ),
        (figures::FRACTIONAL, fractional_figure(&a.fractional)),
    ];
    if !a.by_events.is_empty() {
        images.push((
            figures::ERROR_VS_EVENTS,
            error_bins_figure(
                &a.by_events,
                "events per window",
                "Error against the events per window",
                &a.unit,
            ),
        ));
    }
    if a.coverage.samples > 0 {
        images.push((figures::COVERAGE, coverage_figure(&a.coverage, &a.unit)));
    }
    for (name, img) in images {
        let p = dir.join(name);
        super::save_png(&img, &p)?;
        written.push(p);
    }
    Ok(written)
}

/// Write the report of a comparison into `dir` (created if missing): `agreement.json`,
/// `agreement.csv`, `report.md` with the scatter plot and the |Δv| histogram. Returns the
/// files written.
pub fn write_agreement_report(
    dir: &Path,
    g: &Agreement,
    context: &ReportContext,
) -> Result<Vec<PathBuf>> {
    prepare(dir)?;
    let mut written = Vec::new();
    for (name, body) in [
        ("agreement.json", report::agreement_json(g, context)),
        ("agreement.csv", report::agreement_csv(g)),
        ("report.md", report::agreement_markdown(g, context)),
    ] {
        let p = dir.join(name);
        crate::export::write_text(&p, &body)?;
        written.push(p);
    }
    for (name, img) in [
        (figures::SCATTER, scatter_figure(g)),
        (figures::DIFFERENCES, differences_figure(g)),
    ] {
        let p = dir.join(name);
        super::save_png(&img, &p)?;
        written.push(p);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assess::{assess, compare, AssessOptions, CompareOptions};
    use crate::field::{FieldSeries, Status};

    /// A 12 × 8 grid over two fields with deterministic errors and uncertainties.
    fn series() -> FieldSeries {
        let x = FieldSeries::axis(8.0, 184.0, 16.0);
        let y = FieldSeries::axis(8.0, 120.0, 16.0);
        let mut s = FieldSeries::new(x, y, vec![0, 10_000]);
        for i in 0..s.u.len() {
            let e = ((i as f32 * 0.731).sin()) * 0.05;
            s.u[i] = 1.0 + 0.01 * (i % 12) as f32 + e;
            s.v[i] = 0.5 - e;
            s.u_unc[i] = 0.03;
            s.v_unc[i] = 0.04;
            s.status[i] = Status::VALID;
            s.slab_us[i] = 10_000;
            s.event_count[i] = 50 + (i as u32 * 37) % 400;
        }
        s
    }

    #[test]
    fn reports_write_every_file_and_figure() {
        let s = series();
        let a = assess(
            &s,
            &|x, _, _| (1.0 + 0.01 * ((x - 8.0) / 16.0), 0.5),
            &AssessOptions::default(),
        );
        assert_eq!(a.coverage.samples, 2 * s.u.len());
        let dir = tempfile::tempdir().unwrap();
        let written = write_assessment_report(dir.path(), &a, &Default::default()).unwrap();
        assert_eq!(written.len(), 8);
        for p in &written {
            assert!(std::fs::metadata(p).unwrap().len() > 100, "{}", p.display());
        }
        let img = image::open(dir.path().join(figures::COVERAGE)).unwrap();
        assert!(img.width() > 600 && img.height() > 300);
        let mut b = s.clone();
        b.u.iter_mut().for_each(|u| *u += 0.1);
        let g = compare(&s, &b, &CompareOptions::default()).unwrap();
        let written = write_agreement_report(dir.path(), &g, &Default::default()).unwrap();
        assert_eq!(written.len(), 5);
        if let Some(out) = std::env::var_os("EBIV_FIGURES") {
            for name in [figures::COVERAGE, figures::FRACTIONAL, figures::SCATTER] {
                let _ = std::fs::copy(dir.path().join(name), std::path::Path::new(&out).join(name));
            }
        }
    }
}
