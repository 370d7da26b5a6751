//! The study's figures and its report page, `report.md`: the setup, a table of the main
//! metrics per method and setting (mean ± 95 % confidence half-width over the seeds), the
//! study's numbers beside the published ones it names, and the figures.

use super::cells::{Cell, CellStore};
use super::metrics::{self, polar, rotation_fit, VectorRecord, PLOTTED, PLOTTED_ROTATION};
use super::spec::{Axis, StudySpec};
use super::summary::{value_text, Estimate, Group};
use crate::error::Result;
use crate::render::{
    histogram2d_figure, line_plot, save_png, velocity_histograms, Histogram2d, HistogramStyle,
    LinePlot, Series, SeriesStyle, XAxis,
};
use crate::sim::FlowSpec;
use std::fmt::Write;
use std::path::Path;
use toml::Value;

/// Metrics in the report's table.
const TABLE: [&str; 7] = [
    "rms",
    "bias_u",
    "bias_v",
    "random_u",
    "valid_share",
    "dvr",
    "peak_locking",
];

/// Everything the report is made from.
pub struct ReportInput<'a> {
    /// The study.
    pub spec: &'a StudySpec,
    /// Its cells, in order.
    pub cells: &'a [Cell],
    /// The groups over the seeds ([`super::summary::summarise`]).
    pub groups: &'a [Group],
    /// The store holding the cells' vectors.
    pub store: &'a CellStore,
}

/// Whether the base flow is a solid-body rotation, and its centre and angular velocity.
fn rotation(spec: &StudySpec) -> Option<((f64, f64), f64)> {
    let table = spec.scenario.get("flow")?.clone();
    match table.try_into::<FlowSpec>().ok()? {
        FlowSpec::SolidBody { centre, omega } => Some(((centre[0], centre[1]), omega)),
        _ => None,
    }
}

/// An axis value on a numeric x axis: numbers as they are, durations in ms; `None` for
/// anything else (then the axis is a row of categories).
fn numeric(v: &Value) -> Option<f64> {
    match v {
        Value::Integer(i) => Some(*i as f64),
        Value::Float(f) => Some(*f),
        Value::String(s) if s.ends_with('s') => {
            crate::units::parse_us(s).ok().map(|us| us as f64 / 1000.0)
        }
        _ => None,
    }
}

/// `process.slab` → `process-slab`, for file names.
fn slug(text: &str) -> String {
    let s: String = text
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    s.split('-')
        .filter(|p| !p.is_empty())
        .collect::<Vec<_>>()
        .join("-")
}

/// A group's name: its method and swept values, `corrsum, process.slab = 5ms`.
fn group_label(spec: &StudySpec, g: &Group, skip: Option<usize>) -> String {
    let values = spec.combination(g.combination);
    let mut parts = vec![g.method.clone()];
    for (k, (a, v)) in spec.axes.iter().zip(values).enumerate() {
        if Some(k) != skip && a.values.len() > 1 {
            parts.push(format!("{} = {}", short_key(a), value_text(v)));
        }
    }
    parts.join(", ")
}

/// `process.slab` → `slab`, `scenario.particles.density` → `particles.density`.
fn short_key(a: &Axis) -> String {
    a.key
        .strip_prefix("process.")
        .or_else(|| a.key.strip_prefix("scenario."))
        .unwrap_or(&a.key)
        .to_string()
}

fn metric_label(metric: &str) -> String {
    match metrics::about(metric).0 {
        "" => metric.to_string(),
        unit => format!("{metric} [{unit}]"),
    }
}

/// Write the figures into `out/plots/` and return the report's Markdown, with the figures
/// linked relative to `out`.
pub fn write_report(input: &ReportInput, out: &Path) -> Result<String> {
    let spec = input.spec;
    let plots = out.join("plots");
    std::fs::create_dir_all(&plots).map_err(|e| crate::Error::io(&plots, e))?;
    let mut md = String::new();
    let _ = writeln!(md, "# {}\n", spec.title);
    if !spec.description.is_empty() {
        let _ = writeln!(md, "{}\n", spec.description.trim());
    }
    setup(&mut md, input);
    table(&mut md, input);
    compare(&mut md, input);
    let mut figures = Vec::new();
    if spec.figures.iter().any(|f| f == "radial-profile") {
        figures.extend(radial_profiles(input, &plots)?);
    }
    if spec.figures.iter().any(|f| f == "uv-histogram") {
        figures.extend(uv_histograms(input, &plots)?);
    }
    if spec.figures.iter().any(|f| f == "metrics") {
        figures.extend(metric_plots(input, &plots)?);
    }
    if !figures.is_empty() {
        let _ = writeln!(md, "## Figures\n");
        for (caption, file) in figures {
            let _ = writeln!(md, "**{caption}**\n\n![{caption}](plots/{file})\n");
        }
    }
    let _ = writeln!(
        md,
        "## Files\n\n`results.csv`: one row per cell (method, swept values, seed, every metric). \
         `summary.csv`: one row per method and setting, each metric's mean over the seeds, the \
         half-width of its 95 % confidence interval (`_ci95`, Student's t) and the seeds it rests on (`_n`). \
         `cells/`: one file of metrics and one of valid vectors per cell; a rerun skips the cells found there."
    );
    Ok(md)
}

fn setup(md: &mut String, input: &ReportInput) {
    let spec = input.spec;
    let _ = writeln!(md, "## Setup\n");
    if let Ok(s) = spec.scenario(&spec.combination(0), spec.seeds[0]) {
        let _ = writeln!(
            md,
            "- recording: {} × {} px, `{}` sensor, {} ms, flow `{}`, {} particles/px of {} px",
            s.sensor.width,
            s.sensor.height,
            s.sensor.preset,
            s.duration as f64 / 1000.0,
            s.flow.describe(),
            s.particles.density,
            s.particles.diameter
        );
    }
    let _ = writeln!(
        md,
        "- methods: {}; {} seed(s) ({}); {} field(s) per recording, {} ms margins",
        spec.methods.join(", "),
        spec.seeds.len(),
        spec.seeds
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(", "),
        spec.fields,
        spec.margin_us as f64 / 1000.0
    );
    if !spec.process.is_empty() {
        let pairs: Vec<String> = spec
            .process
            .iter()
            .map(|(k, v)| format!("{k} = {v}"))
            .collect();
        let _ = writeln!(md, "- processing: {}", pairs.join(", "));
    }
    for a in &spec.axes {
        let values: Vec<String> = a.values.iter().map(value_text).collect();
        let _ = writeln!(md, "- swept `{}`: {}", a.key, values.join(", "));
    }
    let _ = writeln!(md, "- cells: {}\n", input.cells.len());
}

fn estimate_text(e: Estimate) -> String {
    if e.n == 0 {
        return "—".into();
    }
    let digits = |x: f64| match x.abs() {
        a if a >= 100.0 => format!("{x:.0}"),
        a if a >= 10.0 => format!("{x:.1}"),
        a if a >= 1.0 => format!("{x:.2}"),
        _ => format!("{x:.4}"),
    };
    if e.ci95.is_finite() {
        format!("{} ± {}", digits(e.mean), digits(e.ci95))
    } else {
        digits(e.mean)
    }
}

fn table(md: &mut String, input: &ReportInput) {
    let spec = input.spec;
    // The peak-locking index means something only for a spread of displacements (a
    // uniform flow's are all alike): shown where the study asks for it.
    let locking = spec.metrics.iter().any(|m| m == "peak_locking")
        || spec.figures.iter().any(|f| f == "uv-histogram");
    let mut metrics: Vec<&str> = TABLE
        .iter()
        .copied()
        .filter(|m| *m != "peak_locking" || locking)
        .collect();
    if rotation(spec).is_some() {
        metrics.extend(["omega_fit", "fit_rms", "fit_dvr"]);
    }
    let _ = writeln!(
        md,
        "## Results\n\nMean over the seeds ± half-width of its 95 % confidence interval; units in `summary.csv`'s metric list below.\n"
    );
    let mut header = String::from("| method |");
    let mut rule = String::from("|---|");
    for a in &spec.axes {
        let _ = write!(header, " {} |", short_key(a));
        rule.push_str("---|");
    }
    for m in &metrics {
        let _ = write!(header, " {} |", metric_label(m));
        rule.push_str("---:|");
    }
    let _ = writeln!(md, "{header}\n{rule}");
    let mut failures = Vec::new();
    for g in input.groups {
        let _ = write!(md, "| {} |", g.method);
        for v in spec.combination(g.combination) {
            let _ = write!(md, " {} |", value_text(v));
        }
        for m in &metrics {
            let _ = write!(md, " {} |", estimate_text(g.get(m)));
        }
        md.push('\n');
        if let (n, Some(reason)) = &g.failed {
            failures.push(format!(
                "- {}: {n} of {} cells could not run: {reason}",
                group_label(spec, g, None),
                g.cells
            ));
        }
    }
    md.push('\n');
    for f in failures {
        let _ = writeln!(md, "{f}");
    }
    let _ = writeln!(md);
    for m in &metrics {
        let (unit, about) = metrics::about(m);
        let unit = if unit.is_empty() {
            String::new()
        } else {
            format!(" [{unit}]")
        };
        let _ = writeln!(md, "- `{m}`{unit}: {about}");
    }
    md.push('\n');
}

fn compare(md: &mut String, input: &ReportInput) {
    let spec = input.spec;
    if spec.compare.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "## Beside the paper\n\n| quantity | ebiv (mean ± 95 % CI) | published | source |\n|---|---:|---:|---|"
    );
    for c in &spec.compare {
        for g in input.groups {
            if c.method.as_ref().is_some_and(|m| m != &g.method) {
                continue;
            }
            let values = spec.combination(g.combination);
            let matches = c.condition.iter().all(|(k, v)| {
                spec.axes
                    .iter()
                    .position(|a| &a.key == k)
                    .is_some_and(|i| values[i] == v)
            });
            if !matches {
                continue;
            }
            let paper = match &c.paper {
                Value::String(s) => s.clone(),
                other => other.to_string(),
            };
            let _ = writeln!(
                md,
                "| {} ({}) | {} | {} | {} |",
                c.metric,
                group_label(spec, g, None),
                estimate_text(g.get(&c.metric)),
                paper,
                c.source
            );
        }
    }
    md.push('\n');
}

/// One figure per plotted metric and swept parameter (and per method when there are
/// several): means with their 95 % bands, a line per method and other setting.
fn metric_plots(input: &ReportInput, plots: &Path) -> Result<Vec<(String, String)>> {
    let spec = input.spec;
    let mut metrics: Vec<&str> = if spec.metrics.is_empty() {
        PLOTTED.to_vec()
    } else {
        spec.metrics.iter().map(String::as_str).collect()
    };
    if spec.metrics.is_empty() && rotation(spec).is_some() {
        metrics.extend(PLOTTED_ROTATION);
    }
    let mut figures = Vec::new();
    // x = a swept parameter (Some(k)) or the method (None).
    let mut xs: Vec<Option<usize>> = (0..spec.axes.len())
        .filter(|&k| spec.axes[k].values.len() > 1)
        .map(Some)
        .collect();
    if spec.methods.len() > 1 && xs.is_empty() {
        xs.push(None);
    }
    for metric in metrics {
        for &x in &xs {
            let plot = metric_plot(input, metric, x);
            let name = match x {
                Some(k) => format!("{metric}-vs-{}.png", slug(&spec.axes[k].key)),
                None => format!("{metric}-by-method.png"),
            };
            save_png(&line_plot(&plot), &plots.join(&name))?;
            figures.push((plot.title.clone(), name));
        }
    }
    Ok(figures)
}

/// Where a group sits on a plot's x axis.
type Position<'a> = Box<dyn Fn(&Group) -> f64 + 'a>;

fn metric_plot(input: &ReportInput, metric: &str, x: Option<usize>) -> LinePlot {
    let spec = input.spec;
    let (x_axis, x_label, position): (XAxis, String, Position) = match x {
        None => (
            XAxis::Categories(spec.methods.clone()),
            "method".into(),
            Box::new(|g: &Group| {
                spec.methods
                    .iter()
                    .position(|m| m == &g.method)
                    .unwrap_or(0) as f64
            }),
        ),
        Some(k) => {
            let axis = &spec.axes[k];
            let all_numeric = axis.values.iter().all(|v| numeric(v).is_some());
            if all_numeric {
                let values: Vec<f64> = axis.values.iter().filter_map(numeric).collect();
                let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let is_duration = matches!(axis.values[0], Value::String(_));
                let label = if is_duration {
                    format!("{} [ms]", axis.key)
                } else {
                    axis.key.clone()
                };
                let x_axis = if lo > 0.0 && hi / lo >= 20.0 {
                    XAxis::Log(values)
                } else {
                    XAxis::Linear
                };
                (
                    x_axis,
                    label,
                    Box::new(move |g: &Group| {
                        numeric(spec.combination(g.combination)[k]).unwrap_or(f64::NAN)
                    }),
                )
            } else {
                let names: Vec<String> = axis.values.iter().map(value_text).collect();
                (
                    XAxis::Categories(names),
                    axis.key.clone(),
                    Box::new(move |g: &Group| {
                        let v = spec.combination(g.combination)[k];
                        spec.axes[k].values.iter().position(|w| w == v).unwrap_or(0) as f64
                    }),
                )
            }
        }
    };
    // One series per group of everything but x.
    let mut series: Vec<(String, Vec<(f64, Estimate)>)> = Vec::new();
    for g in input.groups {
        let label = match x {
            None => group_label(spec, g, None)
                .split_once(", ")
                .map_or(String::new(), |(_, rest)| rest.to_string()),
            Some(k) => group_label(spec, g, Some(k)),
        };
        let point = (position(g), g.get(metric));
        match series.iter_mut().find(|s| s.0 == label) {
            Some(s) => s.1.push(point),
            None => series.push((label, vec![point])),
        }
    }
    let seeds = spec.seeds.len();
    LinePlot {
        title: format!("{metric} against {x_label}"),
        x_label,
        y_label: metric_label(metric),
        x_axis,
        series: series
            .into_iter()
            .map(|(label, mut points)| {
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                Series {
                    label,
                    xy: points.iter().map(|(x, e)| (*x, e.mean)).collect(),
                    band: points
                        .iter()
                        .map(|(_, e)| (e.mean - e.ci95, e.mean + e.ci95))
                        .collect(),
                    style: SeriesStyle::Line,
                    colour: None,
                }
            })
            .collect(),
        notes: vec![format!(
            "mean of {seeds} seed(s), band: 95 % confidence interval of the mean"
        )],
    }
}

/// The valid vectors of a group's cells, pooled over its seeds (the first `seeds` only).
fn group_vectors(input: &ReportInput, g: &Group, seeds: usize) -> Result<Vec<VectorRecord>> {
    let mut out = Vec::new();
    for c in input
        .cells
        .iter()
        .filter(|c| c.method == g.method && c.combination == g.combination)
        .take(seeds)
    {
        if let Ok(v) = input.store.vectors(&c.key) {
            out.extend(v);
        }
    }
    Ok(out)
}

/// Tangential velocity against radius with the linear fit and the truth, one figure per
/// method and setting (the first seed's vectors).
fn radial_profiles(input: &ReportInput, plots: &Path) -> Result<Vec<(String, String)>> {
    let Some((centre, omega)) = rotation(input.spec) else {
        return Ok(Vec::new());
    };
    let mut figures = Vec::new();
    for g in input.groups {
        let vectors = group_vectors(input, g, 1)?;
        let points: Vec<(f64, f64)> = vectors
            .iter()
            .map(|r| polar(r, centre, omega))
            .filter(|p| p.1.is_finite())
            .map(|p| (p.0, p.1))
            .collect();
        let Some(fit) = rotation_fit(&vectors, centre, omega) else {
            continue;
        };
        let r_max = fit.max_radius;
        let label = group_label(input.spec, g, None);
        let plot = LinePlot {
            title: format!("Tangential velocity against radius: {label}"),
            x_label: "radius [px]".into(),
            y_label: "tangential velocity u_t [px/ms]".into(),
            x_axis: XAxis::Linear,
            series: vec![
                Series {
                    label: format!("valid vectors (first seed, {})", points.len()),
                    xy: points,
                    band: vec![],
                    style: SeriesStyle::Markers,
                    colour: Some([90, 90, 90]),
                },
                Series {
                    label: format!(
                        "fit u_t = {:.5} r {:+.4}, rms deviation {:.4} px/ms",
                        fit.slope, fit.intercept, fit.fit_rms
                    ),
                    xy: vec![
                        (0.0, fit.intercept),
                        (r_max, fit.slope * r_max + fit.intercept),
                    ],
                    band: vec![],
                    style: SeriesStyle::Line,
                    colour: Some([213, 94, 0]),
                },
                Series {
                    label: format!("truth u_t = {:.5} r", omega.abs()),
                    xy: vec![(0.0, 0.0), (r_max, omega.abs() * r_max)],
                    band: vec![],
                    style: SeriesStyle::Dashed,
                    colour: Some([0, 114, 178]),
                },
            ],
            notes: vec![],
        };
        let name = format!("radial-{}.png", slug(&label));
        save_png(&line_plot(&plot), &plots.join(&name))?;
        figures.push((plot.title, name));
    }
    Ok(figures)
}

/// The 2-D histogram of the measured (u, v) per method and setting, pooled over the seeds,
/// and of the truth at the same vectors, on one common range.
fn uv_histograms(input: &ReportInput, plots: &Path) -> Result<Vec<(String, String)>> {
    let mut sets = Vec::new();
    for g in input.groups {
        sets.push((g, group_vectors(input, g, usize::MAX)?));
    }
    let truth: Vec<&VectorRecord> = sets
        .first()
        .map(|s| s.1.iter().collect())
        .unwrap_or_default();
    let range = |f: &dyn Fn(&VectorRecord) -> f64| {
        let mut v: Vec<f64> = truth
            .iter()
            .map(|r| f(r))
            .filter(|x| x.is_finite())
            .collect();
        v.sort_by(f64::total_cmp);
        if v.is_empty() {
            return (-1.0, 1.0);
        }
        let (lo, hi) = (v[v.len() / 200], v[v.len() - 1 - v.len() / 200]);
        let pad = 0.15 * (hi - lo).max(0.2);
        (lo - pad, hi + pad)
    };
    let (u_range, v_range) = (range(&|r| r.u_true), range(&|r| r.v_true));
    // Square cells of about 0.02 px/ms, at most 300 per axis.
    let span = (u_range.1 - u_range.0).max(v_range.1 - v_range.0);
    let bins = ((span / 0.02).round() as usize).clamp(40, 300);
    let (u_range, v_range) = (centred(u_range, span), centred(v_range, span));
    let mut figures = Vec::new();
    let draw = |title: String, name: String, u: Vec<f64>, v: Vec<f64>, notes: Vec<String>| {
        let h = Histogram2d::new(&u, &v, u_range, v_range, bins);
        let mut notes = notes;
        notes.insert(
            0,
            format!(
                "{} vectors, {} outside the range, cells of {:.3} px/ms",
                h.total(),
                h.outside,
                span / bins as f64
            ),
        );
        save_png(&histogram2d_figure(&h, &title, &notes), &plots.join(&name))?;
        Ok::<(String, String), crate::Error>((title, name))
    };
    if let Some((g, vectors)) = sets.first() {
        figures.push(draw(
            format!(
                "True (u, v) at the vectors of {}",
                group_label(input.spec, g, None)
            ),
            "uv-truth.png".into(),
            vectors.iter().map(|r| r.u_true).collect(),
            vectors.iter().map(|r| r.v_true).collect(),
            vec![],
        )?);
    }
    for (g, vectors) in &sets {
        let label = group_label(input.spec, g, None);
        let locking = g.get("peak_locking");
        let (u, v): (Vec<f32>, Vec<f32>) = vectors.iter().map(|r| (r.u as f32, r.v as f32)).unzip();
        let style = HistogramStyle {
            bins: 0,
            displacement_ms: Some(g.get("delay_ms").mean).filter(|d| d.is_finite()),
            units: "px/ms".into(),
            title: Some(format!("Velocity histograms: {label}")),
        };
        let name = format!("hist-{}.png", slug(&label));
        save_png(&velocity_histograms(&u, &v, &style), &plots.join(&name))?;
        let title = format!("Velocity and fractional-displacement histograms: {label}");
        figures.push(draw(
            format!("Measured (u, v): {label}"),
            format!("uv-{}.png", slug(&label)),
            vectors.iter().map(|r| r.u).collect(),
            vectors.iter().map(|r| r.v).collect(),
            vec![format!(
                "peak-locking index of the displacements {} (mean over seeds)",
                estimate_text(locking)
            )],
        )?);
        figures.push((title, name));
    }
    Ok(figures)
}

/// `range` widened about its centre to `span`.
fn centred((lo, hi): (f64, f64), span: f64) -> (f64, f64) {
    let c = 0.5 * (lo + hi);
    (c - span / 2.0, c + span / 2.0)
}
