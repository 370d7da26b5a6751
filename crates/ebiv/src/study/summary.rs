//! The study's tables: `results.csv` (one row per cell) and `summary.csv` (one row per
//! method and combination of swept values, each metric's mean over the seeds with its 95 %
//! confidence interval).
//!
//! The interval is mean ± t(0.975, n − 1) · s / √n with the sample standard deviation s
//! (Student 1908; e.g. Montgomery & Runger, Applied Statistics, §8.2): the seeds are
//! independent realisations of the same setup. It is undefined (empty) for a single seed.

use super::cells::{Cell, CellResult};
use super::metrics::METRICS;
use super::spec::StudySpec;
use std::fmt::Write;
use toml::Value;

/// Mean, standard deviation and 95 % confidence half-width of the finite values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Finite values.
    pub n: usize,
    /// Their mean (NaN without values).
    pub mean: f64,
    /// Their sample standard deviation (NaN with fewer than two).
    pub sd: f64,
    /// Half-width of the 95 % confidence interval of the mean (NaN with fewer than two).
    pub ci95: f64,
}

impl Estimate {
    /// The estimate from `values` (non-finite ones are left out).
    pub fn of(values: &[f64]) -> Estimate {
        let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
        let n = finite.len();
        let mean = if n == 0 {
            f64::NAN
        } else {
            finite.iter().sum::<f64>() / n as f64
        };
        let sd = if n < 2 {
            f64::NAN
        } else {
            (finite.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        };
        Estimate {
            n,
            mean,
            sd,
            ci95: student_t975(n.saturating_sub(1)) * sd / (n as f64).sqrt(),
        }
    }
}

/// The 0.975 quantile of Student's t distribution with `df` degrees of freedom (NaN for 0):
/// tabulated to 30, then the normal quantile with the first Cornish–Fisher correction.
pub fn student_t975(df: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    match df {
        0 => f64::NAN,
        d if d <= 30 => TABLE[d - 1],
        d => {
            let z: f64 = 1.959_964;
            z + (z.powi(3) + z) / (4.0 * d as f64)
        }
    }
}

/// One row of the summary: a method and combination, and each metric's estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// The method.
    pub method: String,
    /// Index of the combination of swept values.
    pub combination: usize,
    /// Cells (seeds) in the group, and how many could not run.
    pub cells: usize,
    /// Cells that could not run, with the first reason.
    pub failed: (usize, Option<String>),
    /// The estimate of each metric, in the order of [`METRICS`].
    pub metrics: Vec<(&'static str, Estimate)>,
}

impl Group {
    /// The estimate of `metric`.
    pub fn get(&self, metric: &str) -> Estimate {
        self.metrics
            .iter()
            .find(|(m, _)| *m == metric)
            .map_or(Estimate::of(&[]), |m| m.1)
    }
}

/// The groups of the cells over their seeds, in the order of the cells.
pub fn summarise(cells: &[Cell], results: &[CellResult]) -> Vec<Group> {
    let mut groups: Vec<(String, usize, Vec<&CellResult>)> = Vec::new();
    for (c, r) in cells.iter().zip(results) {
        match groups
            .iter_mut()
            .find(|g| g.0 == c.method && g.1 == c.combination)
        {
            Some(g) => g.2.push(r),
            None => groups.push((c.method.clone(), c.combination, vec![r])),
        }
    }
    groups
        .into_iter()
        .map(|(method, combination, rs)| {
            let failed: Vec<&CellResult> =
                rs.iter().copied().filter(|r| r.error.is_some()).collect();
            Group {
                method,
                combination,
                cells: rs.len(),
                failed: (failed.len(), failed.first().and_then(|r| r.error.clone())),
                metrics: METRICS
                    .iter()
                    .map(|(m, ..)| {
                        let values: Vec<f64> = rs.iter().map(|r| r.get(m)).collect();
                        (*m, Estimate::of(&values))
                    })
                    .collect(),
            }
        })
        .collect()
}

/// A swept value as a CSV field: strings bare, everything else as TOML writes it.
pub fn value_text(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

fn number(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.6e}")
            .parse::<f64>()
            .map_or_else(|_| String::new(), |v| v.to_string())
    } else {
        String::new()
    }
}

/// `results.csv`: one row per cell with its key, method, swept values, seed, every metric
/// and, for cells that could not run, the reason (`note`).
pub fn results_csv(spec: &StudySpec, cells: &[Cell], results: &[CellResult]) -> String {
    let mut out = String::from("key,method");
    for a in &spec.axes {
        let _ = write!(out, ",{}", csv_field(&a.key));
    }
    out.push_str(",seed");
    for (m, ..) in METRICS {
        let _ = write!(out, ",{m}");
    }
    out.push_str(",note\n");
    for (c, r) in cells.iter().zip(results) {
        let _ = write!(out, "{},{}", c.key, c.method);
        for v in spec.combination(c.combination) {
            let _ = write!(out, ",{}", csv_field(&value_text(v)));
        }
        let _ = write!(out, ",{}", c.seed);
        for (m, ..) in METRICS {
            let _ = write!(out, ",{}", number(r.get(m)));
        }
        let _ = writeln!(
            out,
            ",{}",
            csv_field(&r.error.clone().unwrap_or_default().replace('\n', " "))
        );
    }
    out
}

/// `summary.csv`: one row per method and combination: the swept values, the cells and failed
/// cells, and for every metric `_mean`, `_ci95` (half-width of the 95 % interval) and `_n`.
pub fn summary_csv(spec: &StudySpec, groups: &[Group]) -> String {
    let mut out = String::from("method");
    for a in &spec.axes {
        let _ = write!(out, ",{}", csv_field(&a.key));
    }
    out.push_str(",cells,failed");
    for (m, ..) in METRICS {
        let _ = write!(out, ",{m}_mean,{m}_ci95,{m}_n");
    }
    out.push('\n');
    for g in groups {
        out.push_str(&g.method);
        for v in spec.combination(g.combination) {
            let _ = write!(out, ",{}", csv_field(&value_text(v)));
        }
        let _ = write!(out, ",{},{}", g.cells, g.failed.0);
        for (_, e) in &g.metrics {
            let _ = write!(out, ",{},{},{}", number(e.mean), number(e.ci95), e.n);
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_interval_as_by_hand() {
        // 1, 2, 3, 6: mean 3, s² = (4 + 1 + 0 + 9) / 3 = 14/3, t(0.975, 3) = 3.182.
        let e = Estimate::of(&[1.0, 2.0, f64::NAN, 3.0, 6.0]);
        assert_eq!(e.n, 4);
        assert!((e.mean - 3.0).abs() < 1e-12);
        assert!((e.sd - (14.0f64 / 3.0).sqrt()).abs() < 1e-12);
        let half = 3.182 * (14.0f64 / 3.0).sqrt() / 2.0;
        assert!((e.ci95 - half).abs() < 1e-12, "{e:?}");
        let one = Estimate::of(&[0.5]);
        assert_eq!((one.n, one.mean), (1, 0.5));
        assert!(one.sd.is_nan() && one.ci95.is_nan());
        assert!(Estimate::of(&[]).mean.is_nan());
        assert!((student_t975(1) - 12.706).abs() < 1e-9);
        // Beyond the table the approximation meets the exact 2.0003 (df 60) and 1.9840 (100).
        assert!((student_t975(60) - 2.0003).abs() < 2e-3);
        assert!((student_t975(100) - 1.9840).abs() < 1e-3);
    }

    #[test]
    fn groups_pool_the_seeds_of_a_method_and_combination() {
        let cell = |combination, method: &str, seed| Cell {
            combination,
            method: method.into(),
            seed,
            key: format!("{combination}{method}{seed}"),
            recording: String::new(),
        };
        let result = |rms: f64, error: Option<&str>| CellResult {
            key: String::new(),
            metrics: if error.is_none() {
                vec![("rms".into(), rms)]
            } else {
                vec![]
            },
            error: error.map(str::to_string),
        };
        let cells = [
            cell(0, "corrsum", 1),
            cell(0, "corrsum", 2),
            cell(0, "motion", 1),
            cell(0, "motion", 2),
        ];
        let results = [
            result(0.1, None),
            result(0.3, None),
            result(0.0, Some("no events")),
            result(0.2, None),
        ];
        let groups = summarise(&cells, &results);
        assert_eq!(groups.len(), 2);
        let rms = groups[0].get("rms");
        assert!((rms.mean - 0.2).abs() < 1e-12 && rms.n == 2);
        assert!((rms.ci95 - 12.706 * 0.02f64.sqrt() / 2f64.sqrt()).abs() < 1e-9);
        assert_eq!(groups[1].failed, (1, Some("no events".into())));
        assert_eq!(groups[1].get("rms").n, 1);
    }
}
