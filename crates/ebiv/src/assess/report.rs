//! Text outputs of an assessment and of a comparison: JSON (every number), one tidy CSV table,
//! and a Markdown report page that names the figures drawn by
//! [`crate::render::write_assessment_report`].

use super::{Agreement, Assessment, ErrorBin};
use std::fmt::Write;

/// File names of the report's figures, in the order the page shows them.
pub mod figures {
    /// Mean end-point error per grid node.
    pub const ERROR_MAP: &str = "error_map.png";
    /// Errors against the true speed.
    pub const ERROR_VS_SPEED: &str = "error_vs_speed.png";
    /// Errors against the events per window.
    pub const ERROR_VS_EVENTS: &str = "error_vs_events.png";
    /// Histogram of e/σ with the standard normal density, and |e| against σ.
    pub const COVERAGE: &str = "coverage.png";
    /// Fractional-displacement histogram.
    pub const FRACTIONAL: &str = "fractional_displacement.png";
    /// Scatter of a against b per component.
    pub const SCATTER: &str = "scatter.png";
    /// Histogram of |Δv|.
    pub const DIFFERENCES: &str = "differences.png";
}

/// What was assessed, for the report's heading.
#[derive(Debug, Clone, Default)]
pub struct ReportContext {
    /// The field series (file name).
    pub field: String,
    /// Where the truth came from, or the second field of a comparison.
    pub reference: String,
}

/// The assessment as pretty-printed JSON (NaN as `null`).
pub fn assessment_json(a: &Assessment, context: &ReportContext) -> String {
    let value = serde_json::json!({
        "field": context.field,
        "truth": context.reference,
        "assessment": a,
    });
    serde_json::to_string_pretty(&value).unwrap_or_default() + "\n"
}

/// The comparison as pretty-printed JSON, without the per-pair data (NaN as `null`).
pub fn agreement_json(g: &Agreement, context: &ReportContext) -> String {
    let mut value = serde_json::to_value(g).unwrap_or_default();
    if let Some(map) = value.as_object_mut() {
        map.remove("scatter");
        map.remove("differences");
    }
    let value =
        serde_json::json!({ "a": context.field, "b": context.reference, "agreement": value });
    serde_json::to_string_pretty(&value).unwrap_or_default() + "\n"
}

/// Header of the tidy CSV tables.
pub const CSV_HEADER: &str = "group,metric,component,lo,hi,count,value,unit";

fn num(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        "NaN".into()
    }
}

struct Table(String);

impl Table {
    fn new() -> Self {
        Table(format!("{CSV_HEADER}\n"))
    }

    #[allow(clippy::too_many_arguments)]
    fn row(
        &mut self,
        group: &str,
        metric: &str,
        component: &str,
        range: Option<(f64, f64)>,
        count: Option<usize>,
        value: f64,
        unit: &str,
    ) {
        let (lo, hi) = range.map_or((String::new(), String::new()), |(a, b)| (num(a), num(b)));
        let count = count.map_or(String::new(), |c| c.to_string());
        let _ = writeln!(
            self.0,
            "{group},{metric},{component},{lo},{hi},{count},{},{unit}",
            num(value)
        );
    }

    fn bins(&mut self, group: &str, bins: &[ErrorBin], unit: &str) {
        for b in bins {
            let r = Some((b.lo, b.hi));
            self.row(group, "aee", "", r, Some(b.count), b.aee, unit);
            self.row(group, "rms", "", r, Some(b.count), b.rms, unit);
            self.row(group, "bias", "u", r, Some(b.count), b.bias[0], unit);
            self.row(group, "bias", "v", r, Some(b.count), b.bias[1], unit);
        }
    }
}

/// The assessment as one tidy table ([`CSV_HEADER`]): one value per row; groups `summary`,
/// `by_speed` and `by_events` (lo, hi: the bin), `coverage`, `fractional` (lo, hi: the bin
/// in px) and `error_map` (lo, hi: the node's x and y in px).
pub fn assessment_csv(a: &Assessment) -> String {
    let mut t = Table::new();
    let u = a.unit.as_str();
    let n = Some(a.compared);
    for (metric, count, value, unit) in [
        ("total", None, a.total as f64, "1"),
        ("valid", None, a.valid as f64, "1"),
        ("compared", None, a.compared as f64, "1"),
        ("without_truth", None, a.without_truth as f64, "1"),
        ("valid_share", Some(a.total), a.valid_share, "1"),
        ("rms", n, a.rms, u),
        ("aee", n, a.aee, u),
        ("median", n, a.median, u),
        ("max", n, a.max, u),
        ("outliers", n, a.outliers as f64, "1"),
        ("outlier_share", n, a.outlier_share, "1"),
        ("rms_without_outliers", n, a.rms_without_outliers, u),
        ("max_true_speed", n, a.max_true_speed, u),
        ("dvr", n, a.dvr, "1"),
    ] {
        t.row("summary", metric, "", None, count, value, unit);
    }
    for (k, c) in ["u", "v"].iter().enumerate() {
        t.row("summary", "bias", c, None, n, a.bias[k], u);
        t.row("summary", "random", c, None, n, a.random[k], u);
    }
    t.bins("by_speed", &a.by_speed, u);
    t.bins("by_events", &a.by_events, u);
    let c = &a.coverage;
    let s = Some(c.samples);
    t.row("coverage", "samples", "uv", None, s, c.samples as f64, "1");
    let without = c.without_uncertainty as f64;
    t.row(
        "coverage",
        "without_uncertainty",
        "uv",
        None,
        None,
        without,
        "1",
    );
    t.row(
        "coverage",
        "within_1_sigma",
        "uv",
        None,
        s,
        c.within_1_sigma,
        "1",
    );
    t.row(
        "coverage",
        "within_2_sigma",
        "uv",
        None,
        s,
        c.within_2_sigma,
        "1",
    );
    t.row("coverage", "spearman", "uv", None, s, c.spearman, "1");
    t.row(
        "coverage",
        "rms_normalised",
        "uv",
        None,
        s,
        c.rms_normalised,
        "1",
    );
    let f = &a.fractional;
    for (b, &count) in f.counts.iter().enumerate() {
        let r = Some((f.edge(b), f.edge(b + 1)));
        t.row("fractional", "count", "uv", r, None, count as f64, "1");
    }
    let samples = Some(f.samples as usize);
    t.row(
        "fractional",
        "peak_locking_index",
        "uv",
        None,
        samples,
        f.peak_locking_index,
        "1",
    );
    t.row(
        "fractional",
        "noise_level",
        "uv",
        None,
        samples,
        f.noise_level,
        "1",
    );
    let m = &a.error_map;
    for (row, &y) in m.y.iter().enumerate() {
        for (col, &x) in m.x.iter().enumerate() {
            let i = row * m.x.len() + col;
            if m.count[i] > 0 {
                let r = Some((x, y));
                t.row(
                    "error_map",
                    "aee",
                    "",
                    r,
                    Some(m.count[i]),
                    m.mean_error[i],
                    u,
                );
            }
        }
    }
    t.0
}

/// The comparison as one tidy table ([`CSV_HEADER`]), group `agreement`.
pub fn agreement_csv(g: &Agreement) -> String {
    let mut t = Table::new();
    let u = g.unit.as_str();
    let n = Some(g.compared);
    for (metric, component, value, unit) in [
        ("fields_matched", "", g.pairs.len() as f64, "1"),
        ("fields_unmatched", "", g.unmatched_fields as f64, "1"),
        ("a_valid", "", g.a_valid as f64, "1"),
        ("compared", "", g.compared as f64, "1"),
        ("without_b", "", g.without_b as f64, "1"),
        ("median_difference", "", g.median_difference, u),
        ("mean_difference", "", g.mean_difference, u),
        ("rms_difference", "", g.rms_difference, u),
        (
            "mean_component_difference",
            "u",
            g.mean_component_difference[0],
            u,
        ),
        (
            "mean_component_difference",
            "v",
            g.mean_component_difference[1],
            u,
        ),
        (
            "sd_component_difference",
            "u",
            g.sd_component_difference[0],
            u,
        ),
        (
            "sd_component_difference",
            "v",
            g.sd_component_difference[1],
            u,
        ),
        ("threshold", "", g.threshold, u),
        ("beyond_share", "", g.beyond_share, "1"),
    ] {
        t.row("agreement", metric, component, None, n, value, unit);
    }
    t.0
}

fn pct(x: f64) -> String {
    if x.is_finite() {
        format!("{:.1} %", 100.0 * x)
    } else {
        "–".into()
    }
}

fn val(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.4}")
    } else {
        "–".into()
    }
}

/// A few lines for a terminal: the headline numbers of an assessment.
pub fn assessment_summary(a: &Assessment) -> String {
    let u = &a.unit;
    let c = &a.coverage;
    let f = &a.fractional;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "vectors: {} valid of {} ({}), {} compared with the truth",
        a.valid,
        a.total,
        pct(a.valid_share),
        a.compared
    );
    let _ = writeln!(
        s,
        "error: RMS {} {u}, mean |e| (AEE) {} {u}, median {} {u}, max {} {u}",
        val(a.rms),
        val(a.aee),
        val(a.median),
        val(a.max)
    );
    let _ = writeln!(
        s,
        "bias (u, v): ({}, {}) {u}; random (u, v): ({}, {}) {u}",
        val(a.bias[0]),
        val(a.bias[1]),
        val(a.random[0]),
        val(a.random[1])
    );
    let _ = writeln!(
        s,
        "outliers: {} ({}) above {}–{} {u}; RMS without them {} {u}",
        a.outliers,
        pct(a.outlier_share),
        val(a.outlier_threshold[0]),
        val(a.outlier_threshold[1]),
        val(a.rms_without_outliers)
    );
    let _ = writeln!(
        s,
        "dynamic velocity range: {} (largest true speed {} {u} / RMS error)",
        if a.dvr.is_finite() {
            format!("{:.0}", a.dvr)
        } else {
            "–".into()
        },
        val(a.max_true_speed)
    );
    if c.samples > 0 {
        let _ = writeln!(
            s,
            "uncertainty coverage: {} within ±1σ (68.3 % expected), {} within ±2σ (95.4 %), \
             Spearman(|e|, σ) {:.2}, {} components without σ",
            pct(c.within_1_sigma),
            pct(c.within_2_sigma),
            c.spearman,
            c.without_uncertainty
        );
    } else {
        let _ = writeln!(
            s,
            "uncertainty coverage: no vector carries an uncertainty ({} components without σ)",
            c.without_uncertainty
        );
    }
    let _ = writeln!(
        s,
        "peak locking: index {} from {} displacement components (noise alone: about {})",
        val(f.peak_locking_index),
        f.samples,
        val(f.noise_level)
    );
    s
}

/// A few lines for a terminal: the headline numbers of a comparison.
pub fn agreement_summary(g: &Agreement) -> String {
    let u = &g.unit;
    format!(
        "fields: {} matched, {} of the first without a match\n\
         vectors: {} compared ({} valid in the first, {} without a value of the second{})\n\
         median |Δv| {} {u}, mean {} {u}, RMS {} {u}; {} differ by more than {} {u}\n\
         mean difference a − b (u, v): ({}, {}) {u}, standard deviation ({}, {}) {u}\n",
        g.pairs.len(),
        g.unmatched_fields,
        g.compared,
        g.a_valid,
        g.without_b,
        if g.interpolated {
            "; the second interpolated to the first's grid"
        } else {
            ""
        },
        val(g.median_difference),
        val(g.mean_difference),
        val(g.rms_difference),
        pct(g.beyond_share),
        g.threshold,
        val(g.mean_component_difference[0]),
        val(g.mean_component_difference[1]),
        val(g.sd_component_difference[0]),
        val(g.sd_component_difference[1]),
    )
}

/// The Markdown report page of an assessment, showing the figures of [`figures`].
pub fn assessment_markdown(a: &Assessment, context: &ReportContext) -> String {
    let u = &a.unit;
    let c = &a.coverage;
    let f = &a.fractional;
    let mut s = String::new();
    let _ = writeln!(s, "# Assessment of `{}`\n", context.field);
    let _ = writeln!(s, "Truth: {}.\n", context.reference);
    let _ = writeln!(
        s,
        "Errors are e = measured − true, in {u}, over the valid vectors (status 0) where the \
         truth is known. `docs/assess.md` defines every metric.\n"
    );
    let _ = writeln!(s, "| metric | value |\n|---|---|");
    let rows = [
        ("vectors", a.total.to_string()),
        ("valid", format!("{} ({})", a.valid, pct(a.valid_share))),
        ("compared with the truth", a.compared.to_string()),
        ("RMS end-point error", format!("{} {u}", val(a.rms))),
        ("mean end-point error (AEE)", format!("{} {u}", val(a.aee))),
        ("median end-point error", format!("{} {u}", val(a.median))),
        (
            "bias (u, v)",
            format!("({}, {}) {u}", val(a.bias[0]), val(a.bias[1])),
        ),
        (
            "random error (u, v)",
            format!("({}, {}) {u}", val(a.random[0]), val(a.random[1])),
        ),
        (
            "outliers",
            format!(
                "{} ({}), threshold {}–{} {u}",
                a.outliers,
                pct(a.outlier_share),
                val(a.outlier_threshold[0]),
                val(a.outlier_threshold[1])
            ),
        ),
        (
            "RMS error without outliers",
            format!("{} {u}", val(a.rms_without_outliers)),
        ),
        (
            "largest true speed",
            format!("{} {u}", val(a.max_true_speed)),
        ),
        ("dynamic velocity range", val(a.dvr)),
        ("within ±1σ (68.3 % expected)", pct(c.within_1_sigma)),
        ("within ±2σ (95.4 % expected)", pct(c.within_2_sigma)),
        ("Spearman rank correlation of abs(e) and σ", val(c.spearman)),
        ("peak-locking index", val(f.peak_locking_index)),
    ];
    for (k, v) in rows {
        let _ = writeln!(s, "| {k} | {v} |");
    }
    let _ = writeln!(
        s,
        "\n## Where the errors are\n\n![mean end-point error per node]({})\n\n\
         The mean end-point error of each grid node over all fields. Large values along the \
         edges point at windows that reach out of the flow or the sensor; patches inside, at \
         strong gradients or too few events.\n",
        figures::ERROR_MAP
    );
    let _ = writeln!(
        s,
        "## Error against speed and events\n\n![errors against the true speed]({})\n\n\
         Mean and RMS end-point error in bins of the true speed. An error growing with speed \
         is a relative error (e.g. too short a slab to resolve the displacement, or gradient \
         bias); a constant error is the estimator's noise floor.\n",
        figures::ERROR_VS_SPEED
    );
    if a.by_events.is_empty() {
        let _ = writeln!(
            s,
            "The field carries no event counts: no errors against events.\n"
        );
    } else {
        let _ = writeln!(
            s,
            "![errors against the events per window]({})\n\n\
             Mean and RMS end-point error in bins of the events per window (equal numbers of \
             vectors per bin). Errors that fall with more events are limited by the seeding \
             or the slab length.\n",
            figures::ERROR_VS_EVENTS
        );
    }
    let _ = writeln!(s, "## Uncertainty coverage\n");
    if c.samples == 0 {
        let _ = writeln!(
            s,
            "No valid vector carries a standard uncertainty ({} components without one).\n",
            c.without_uncertainty
        );
    } else {
        let _ = writeln!(
            s,
            "![coverage of the uncertainty]({})\n\n\
             Left: the errors divided by their standard uncertainty, e/σ, both components \
             pooled, against the standard normal density (the curve). Well-estimated \
             uncertainties give a histogram that follows the curve: {} of e/σ within ±1 \
             (68.3 % expected) and {} within ±2 (95.4 % expected); the RMS of e/σ is {}. \
             A narrower histogram means σ overestimates the errors; a wider one, or tails, that \
             it underestimates them. Right: |e| against σ; the Spearman rank correlation {} \
             says how well σ ranks the vectors by their error (1: perfectly). {} components \
             had no uncertainty and are left out.\n",
            figures::COVERAGE,
            pct(c.within_1_sigma),
            pct(c.within_2_sigma),
            val(c.rms_normalised),
            val(c.spearman),
            c.without_uncertainty
        );
    }
    let _ = writeln!(
        s,
        "## Peak locking\n\n![fractional displacement]({})\n\n\
         The fractional part of the measured displacement (velocity × the vector's time slab), \
         d − round(d) in px, both components. An estimator without peak locking gives a flat \
         histogram when the displacements spread over more than a pixel; peak locking piles \
         the values up around 0 (whole pixels). The peak-locking index is Christensen's \
         (2004) 1 − H_min/H_max of this histogram: 0 flat, 1 every displacement a whole \
         pixel. Here it is {} from {} values; sampling noise alone gives about {}, so only an \
         index well above that, with a peak at 0, shows locking.{}\n",
        figures::FRACTIONAL,
        val(f.peak_locking_index),
        f.samples,
        val(f.noise_level),
        if f.without_slab > 0 {
            format!(
                " {} valid vectors without a time slab are left out.",
                f.without_slab
            )
        } else {
            String::new()
        }
    );
    s
}

/// The Markdown report page of a comparison.
pub fn agreement_markdown(g: &Agreement, context: &ReportContext) -> String {
    let u = &g.unit;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Agreement of `{}` (a) and `{}` (b)\n",
        context.field, context.reference
    );
    let _ = writeln!(s, "| metric | value |\n|---|---|");
    let rows = [
        ("fields matched in time", g.pairs.len().to_string()),
        ("vectors compared", g.compared.to_string()),
        (
            "valid vectors of a without a value of b",
            g.without_b.to_string(),
        ),
        (
            "median abs(Δv)",
            format!("{} {u}", val(g.median_difference)),
        ),
        ("mean abs(Δv)", format!("{} {u}", val(g.mean_difference))),
        ("RMS abs(Δv)", format!("{} {u}", val(g.rms_difference))),
        (
            "share with abs(Δv) above the threshold",
            format!("{} (threshold {} {u})", pct(g.beyond_share), g.threshold),
        ),
        (
            "mean difference a − b (u, v)",
            format!(
                "({}, {}) {u}",
                val(g.mean_component_difference[0]),
                val(g.mean_component_difference[1])
            ),
        ),
    ];
    for (k, v) in rows {
        let _ = writeln!(s, "| {k} | {v} |");
    }
    let _ = writeln!(
        s,
        "\n{}\n\n![a against b]({})\n\nEach valid vector of a against the value of b at the \
         same place and time, per component; points on the diagonal agree.\n\n\
         ![histogram of abs(Δv)]({})\n\nThe end-point differences |v_a − v_b|, with the median \
         and the threshold marked.\n",
        if g.interpolated {
            "The grids differ: b is interpolated bilinearly to a's nodes."
        } else {
            "Both fields lie on the same grid."
        },
        figures::SCATTER,
        figures::DIFFERENCES
    );
    s
}
