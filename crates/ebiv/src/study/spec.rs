//! The study file: what to simulate, how to process it, what to sweep, how often to repeat
//! it, and which published numbers to put beside the results. Read with
//! [`StudySpec::from_toml`]; every problem is reported with the key it concerns.
//!
//! ```toml
//! title = "Seeding density"
//! seeds = 3                              # or a list of scenario seeds: [1, 5, 9]
//! methods = ["corrsum", "motion"]        # corrsum, motion, piv, pulsed
//! fields = 3                             # fields per recording, spread over it
//!
//! [scenario]                             # the base recording
//! example = "uniform"                    # or file = "scene.toml", or a whole scenario here
//! duration = "60ms"                      # any scenario key overrides the base
//! sensor = { width = 192, height = 192, preset = "ideal" }
//!
//! [process]                              # `ebiv process` configuration keys
//! window = [64, 32]
//!
//! [variants.motion-grid]                 # a named method with settings of its own
//! method = "motion"
//! motion-search = "grid"
//!
//! [sweep]                                # one axis per key; cells are every combination
//! "scenario.particles.density" = [0.002, 0.01, 0.05]
//! "process.slab" = ["5ms", "10ms"]
//!
//! [[compare]]                            # a published number for the report
//! metric = "rms"
//! method = "corrsum"
//! where = { "process.slab" = "10ms" }
//! paper = 0.02
//! source = "Willert & Klinner 2022, Exp. Fluids 63:101"
//! ```

use crate::error::{Error, Result};
use crate::process::Method;
use crate::settings::ProcessSettings;
use crate::sim::scenario::{line_of, Scenario};
use std::collections::BTreeMap;
use std::path::Path;
use toml::{Table, Value};

/// Fields per recording when `fields` is not given.
pub const DEFAULT_FIELDS: usize = 3;
/// Time left out at each end of a recording when `margin` is not given, µs.
pub const DEFAULT_MARGIN_US: i64 = 5_000;
/// Most cells (combinations × methods × seeds) a study may hold: a guard against a mistyped
/// sweep that would take years.
pub const MAX_CELLS: usize = 100_000;

/// Where a sweep key points.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub enum Target {
    /// A key path in the scenario (`flow.u`, `sensor.refractory_us`).
    Scenario(Vec<String>),
    /// An `ebiv process` setting (`window`, `slab`).
    Process(String),
}

/// One swept parameter: its key as written and its values.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// The key as written in `[sweep]` (`scenario.flow.u`, `sensor.refractory_us`,
    /// `process.window`).
    pub key: String,
    /// What it sets.
    pub target: Target,
    /// The values, in the order given.
    pub values: Vec<Value>,
}

/// A published number to put beside the study's own ([`StudySpec::compare`]).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Comparison {
    /// The study's metric (a column of `results.csv`).
    pub metric: String,
    /// The method whose cells are compared; all methods when left out.
    #[serde(default)]
    pub method: Option<String>,
    /// Swept values the compared cells must have (`{ "process.slab" = "10ms" }`).
    #[serde(default, rename = "where")]
    pub condition: BTreeMap<String, Value>,
    /// The published value: a number, or a text for a qualitative finding.
    pub paper: Value,
    /// Where it is published, and under which conditions.
    pub source: String,
}

/// The study file as written.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct StudyFile {
    #[serde(default)]
    title: Option<String>,
    #[serde(default)]
    description: Option<String>,
    seeds: Seeds,
    #[serde(default)]
    methods: Option<Vec<String>>,
    #[serde(default)]
    fields: Option<usize>,
    #[serde(default)]
    margin: Option<Value>,
    scenario: Table,
    #[serde(default)]
    process: Table,
    #[serde(default)]
    variants: Table,
    #[serde(default)]
    sweep: Table,
    #[serde(default)]
    figures: Option<Vec<String>>,
    #[serde(default)]
    metrics: Option<Vec<String>>,
    #[serde(default)]
    compare: Vec<Comparison>,
}

#[derive(Debug, Clone, serde::Deserialize)]
#[serde(untagged)]
enum Seeds {
    Count(i64),
    List(Vec<i64>),
}

/// Extra figures a study may ask for besides the metric plots.
pub const FIGURES: [(&str, &str); 3] = [
    (
        "metrics",
        "each plotted metric against each swept parameter, mean and 95 % band",
    ),
    (
        "radial-profile",
        "tangential velocity against radius with its linear fit (solid-body flows)",
    ),
    (
        "uv-histogram",
        "2-D histogram of the measured (u, v) per method and setting, and of the truth",
    ),
];

/// A parsed and checked study.
#[derive(Debug, Clone, PartialEq)]
pub struct StudySpec {
    /// Title of the report.
    pub title: String,
    /// What the study is for, a paragraph of the report.
    pub description: String,
    /// Scenario seeds: every combination is simulated once per seed.
    pub seeds: Vec<u64>,
    /// Methods, as `ebiv process --method` takes them, or names of [`StudySpec::variants`].
    pub methods: Vec<String>,
    /// Named methods with settings of their own: name → a table of `method` and `ebiv
    /// process` keys applied over `[process]` (the paper's grid search of motion
    /// compensation beside ebiv's default, say).
    pub variants: Table,
    /// Fields evaluated per recording, spread evenly between the margins.
    pub fields: usize,
    /// Time left out at each end of a recording, µs.
    pub margin_us: i64,
    /// The base scenario, resolved to one table (example or file, with the overrides).
    pub scenario: Table,
    /// The base `ebiv process` settings table.
    pub process: Table,
    /// The swept parameters, in key order.
    pub axes: Vec<Axis>,
    /// Figures to draw ([`FIGURES`]).
    pub figures: Vec<String>,
    /// Metrics to plot (columns of `results.csv`); empty: the standard set.
    pub metrics: Vec<String>,
    /// Published numbers to compare with.
    pub compare: Vec<Comparison>,
}

/// `key: message` as a parameter error of the study file.
fn bad(key: impl Into<String>, message: impl Into<String>) -> Error {
    Error::parameter(key, message)
}

impl StudySpec {
    /// Read a study from TOML. `origin` names it in errors (a file name, `example NAME`);
    /// `base_dir` resolves a relative `scenario.file`. Every combination's scenario and
    /// settings are built once here, so that a bad value fails before anything runs.
    pub fn from_toml(text: &str, origin: &str, base_dir: &Path) -> Result<StudySpec> {
        let file: StudyFile = toml::from_str(text).map_err(|e| Error::Parse {
            context: origin.to_string(),
            line: e.span().map_or(0, |s| line_of(text, s.start)),
            message: e.message().to_string(),
        })?;
        let seeds: Vec<u64> = match file.seeds {
            Seeds::Count(n) if (1..=10_000).contains(&n) => (1..=n as u64).collect(),
            Seeds::Count(n) => return Err(bad("seeds", format!("{n}: give 1 to 10000 seeds"))),
            Seeds::List(list) if list.is_empty() => {
                return Err(bad("seeds", "the list is empty: give at least one seed"))
            }
            Seeds::List(list) => {
                let mut seeds = Vec::new();
                for s in list {
                    let s = u64::try_from(s)
                        .map_err(|_| bad("seeds", format!("{s}: seeds are not negative")))?;
                    if seeds.contains(&s) {
                        return Err(bad("seeds", format!("{s} is given twice")));
                    }
                    seeds.push(s);
                }
                seeds
            }
        };
        let methods = file.methods.unwrap_or_else(|| vec!["corrsum".into()]);
        if methods.is_empty() {
            return Err(bad("methods", "give at least one method"));
        }
        for (name, variant) in &file.variants {
            let key = format!("variants.{name}");
            let table = variant
                .as_table()
                .ok_or_else(|| bad(&key, "give a table: method = \"motion\" and settings"))?;
            if Method::parse(name).is_some() {
                return Err(bad(&key, "a variant needs a name other than a method's"));
            }
            match table.get("method") {
                Some(Value::String(m)) if Method::parse(m).is_some() => {}
                _ => {
                    return Err(bad(
                        format!("{key}.method"),
                        "name a method: corrsum, motion, piv or pulsed",
                    ))
                }
            }
            for k in table.keys().filter(|k| *k != "method") {
                check_process_key(k, &format!("{key}.{k}"))?;
            }
        }
        for (i, m) in methods.iter().enumerate() {
            if Method::parse(m).is_none() && !file.variants.contains_key(m) {
                return Err(bad(
                    "methods",
                    format!("`{m}` is not a method or variant; use corrsum, motion, piv, pulsed or a name of [variants]"),
                ));
            }
            if methods[..i].contains(m) {
                return Err(bad("methods", format!("`{m}` is given twice")));
            }
        }
        let fields = file.fields.unwrap_or(DEFAULT_FIELDS);
        if !(1..=1000).contains(&fields) {
            return Err(bad("fields", format!("{fields}: give 1 to 1000 fields")));
        }
        let margin_us = match &file.margin {
            None => DEFAULT_MARGIN_US,
            Some(Value::String(s)) => crate::units::parse_us(s).map_err(|e| bad("margin", e))?,
            Some(Value::Integer(us)) => *us,
            Some(other) => return Err(bad("margin", format!("`{other}` is not a duration"))),
        };
        if margin_us < 0 {
            return Err(bad("margin", "must not be negative"));
        }
        let scenario = base_scenario(file.scenario, base_dir)?;
        for key in file.process.keys() {
            check_process_key(key, &format!("process.{key}"))?;
        }
        let mut axes = Vec::new();
        for (key, values) in file.sweep {
            let target = sweep_target(&key)?;
            let values = match values {
                Value::Array(v) if !v.is_empty() => v,
                Value::Array(_) => return Err(bad(sweep_name(&key), "the list is empty")),
                other => {
                    return Err(bad(
                        sweep_name(&key),
                        format!("`{other}`: give a list of values, e.g. [1, 2]"),
                    ))
                }
            };
            for (i, v) in values.iter().enumerate() {
                if values[..i].contains(v) {
                    return Err(bad(sweep_name(&key), format!("{v} is given twice")));
                }
            }
            axes.push(Axis {
                key,
                target,
                values,
            });
        }
        let figures = file.figures.unwrap_or_else(|| vec!["metrics".into()]);
        for f in &figures {
            if !FIGURES.iter().any(|(name, _)| name == f) {
                let names: Vec<&str> = FIGURES.iter().map(|f| f.0).collect();
                return Err(bad(
                    "figures",
                    format!("`{f}` is not a figure; use {}", names.join(", ")),
                ));
            }
        }
        let metrics = file.metrics.unwrap_or_default();
        for m in &metrics {
            if !super::metrics::is_metric(m) {
                return Err(bad(
                    "metrics",
                    format!(
                        "`{m}` is not a metric; use {}",
                        super::metrics::names().join(", ")
                    ),
                ));
            }
        }
        for (i, c) in file.compare.iter().enumerate() {
            let key = format!("compare[{i}]");
            if !super::metrics::is_metric(&c.metric) {
                return Err(bad(
                    format!("{key}.metric"),
                    format!("`{}` is not a metric", c.metric),
                ));
            }
            if let Some(m) = &c.method {
                if !methods.contains(m) {
                    return Err(bad(
                        format!("{key}.method"),
                        format!("`{m}` is not one of the study's methods"),
                    ));
                }
            }
            for (k, v) in &c.condition {
                let axis = axes.iter().find(|a| &a.key == k).ok_or_else(|| {
                    bad(format!("{key}.where"), format!("`{k}` is not a swept key"))
                })?;
                if !axis.values.contains(v) {
                    return Err(bad(
                        format!("{key}.where"),
                        format!("{v} is not one of the values of `{k}`"),
                    ));
                }
            }
        }
        let spec = StudySpec {
            title: file.title.unwrap_or_else(|| origin.to_string()),
            description: file.description.unwrap_or_default(),
            seeds,
            methods,
            variants: file.variants,
            fields,
            margin_us,
            scenario,
            process: file.process,
            axes,
            figures,
            metrics,
            compare: file.compare,
        };
        spec.check_cells()?;
        Ok(spec)
    }

    /// Number of combinations of the swept values (without methods and seeds).
    pub fn combinations(&self) -> usize {
        self.axes.iter().map(|a| a.values.len()).product()
    }

    /// The swept values of combination `index` (the last axis varies fastest).
    pub fn combination(&self, mut index: usize) -> Vec<&Value> {
        let mut values: Vec<&Value> = Vec::with_capacity(self.axes.len());
        for axis in self.axes.iter().rev() {
            values.push(&axis.values[index % axis.values.len()]);
            index /= axis.values.len();
        }
        values.reverse();
        values
    }

    /// The scenario table of a combination and seed: the base with the swept scenario keys
    /// and the seed set.
    pub fn scenario_table(&self, values: &[&Value], seed: u64) -> Table {
        let mut table = self.scenario.clone();
        for (axis, value) in self.axes.iter().zip(values) {
            if let Target::Scenario(path) = &axis.target {
                set_path(&mut table, path, (*value).clone());
            }
        }
        table.insert("seed".into(), Value::Integer(seed as i64));
        table
    }

    /// The scenario of a combination and seed, checked; errors name the combination.
    pub fn scenario(&self, values: &[&Value], seed: u64) -> Result<Scenario> {
        let table = self.scenario_table(values, seed);
        let text = toml::to_string(&table).map_err(|e| bad("scenario", e.to_string()))?;
        let context = format!("scenario of {}", describe(&self.axes, values));
        let scenario = Scenario::from_toml(&text, &context).map_err(|e| match e {
            Error::Parse { message, .. } => bad(context.clone(), message),
            other => other,
        })?;
        scenario.simulation().map_err(|e| in_context(e, &context))?;
        Ok(scenario)
    }

    /// The `ebiv process` settings of a combination and method, as the configuration file
    /// would give them; errors name the key.
    pub fn settings(&self, values: &[&Value], method: &str) -> Result<ProcessSettings> {
        let mut s = ProcessSettings {
            input: Some("simulated recording".into()),
            ..ProcessSettings::default()
        };
        s.apply_table(&self.process)
            .map_err(|e| in_context(e, "[process]"))?;
        let name = method;
        let mut method = name.to_string();
        if let Some(Value::Table(variant)) = self.variants.get(name) {
            let mut own = variant.clone();
            if let Some(Value::String(m)) = own.remove("method") {
                method = m;
            }
            s.apply_table(&own)
                .map_err(|e| in_context(e, &format!("[variants.{name}]")))?;
        }
        for (axis, value) in self.axes.iter().zip(values) {
            if let Target::Process(key) = &axis.target {
                s.set(key, value)
                    .map_err(|e| in_context(e, &format!("sweep `{}` = {value}", axis.key)))?;
            }
        }
        s.set("method", &Value::String(method))?;
        Ok(s)
    }

    /// Build every combination's scenario and every combination's settings for every
    /// method once, so that a bad value stops the study before it starts.
    fn check_cells(&self) -> Result<()> {
        let cells = self.combinations() * self.methods.len() * self.seeds.len();
        if cells > MAX_CELLS {
            return Err(bad(
                "sweep",
                format!("{cells} cells, more than {MAX_CELLS}: sweep fewer values or seeds"),
            ));
        }
        for c in 0..self.combinations() {
            let values = self.combination(c);
            self.scenario(&values, self.seeds[0])?;
            for m in &self.methods {
                let context = format!("{m}, {}", describe(&self.axes, &values));
                self.settings(&values, m)?
                    .resolve()
                    .map_err(|e| in_context(e, &context))?;
            }
        }
        Ok(())
    }
}

/// `scenario.flow.u = 0.5, process.slab = "5ms"` (or `base settings` without axes).
pub fn describe(axes: &[Axis], values: &[&Value]) -> String {
    if axes.is_empty() {
        return "the base settings".into();
    }
    axes.iter()
        .zip(values)
        .map(|(a, v)| format!("{} = {v}", a.key))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A parameter error with `context` added to its message.
fn in_context(e: Error, context: &str) -> Error {
    match e {
        Error::Parameter { name, message } => Error::Parameter {
            name,
            message: format!("{message} (in {context})"),
        },
        other => other,
    }
}

fn sweep_name(key: &str) -> String {
    format!("sweep.\"{key}\"")
}

/// What a sweep key sets: `scenario.PATH`, `sensor.KEY` (short for `scenario.sensor.KEY`)
/// or `process.KEY`.
fn sweep_target(key: &str) -> Result<Target> {
    let name = sweep_name(key);
    let (head, rest) = key.split_once('.').unwrap_or((key, ""));
    let path: Vec<String> = rest.split('.').map(str::to_string).collect();
    if rest.is_empty() || path.iter().any(String::is_empty) {
        return Err(bad(
            name,
            "use scenario.KEY (e.g. scenario.flow.u), sensor.KEY or process.KEY",
        ));
    }
    match head {
        "scenario" if path == ["seed"] => Err(bad(name, "give the seeds with `seeds`")),
        "scenario" => Ok(Target::Scenario(path)),
        "sensor" => Ok(Target::Scenario(
            std::iter::once("sensor".to_string()).chain(path).collect(),
        )),
        "process" => {
            check_process_key(rest, &name)?;
            Ok(Target::Process(rest.to_string()))
        }
        _ => Err(bad(
            name,
            format!("`{head}` is not scenario, sensor or process"),
        )),
    }
}

/// A key of `[process]` or a swept `process.KEY`: a known setting other than the input,
/// output and method (the study gives those).
fn check_process_key(key: &str, name: &str) -> Result<()> {
    let setting = crate::settings::find(key).ok_or_else(|| {
        bad(
            name,
            format!("`{key}` is not an `ebiv process` setting (see `ebiv init`)"),
        )
    })?;
    match setting.key {
        "method" => Err(bad(name, "give the methods with `methods`")),
        "input" | "output" | "png" | "images" | "time" | "absolute-time" => Err(bad(
            name,
            format!("`{key}` is set by the study for each simulated recording"),
        )),
        _ => Ok(()),
    }
}

/// The base scenario: `example = NAME` or `file = PATH` with the other keys merged over it,
/// or the table itself.
fn base_scenario(mut table: Table, base_dir: &Path) -> Result<Table> {
    let example = table.remove("example");
    let file = table.remove("file");
    let base_text = match (example, file) {
        (Some(_), Some(_)) => {
            return Err(bad("scenario", "give either `example` or `file`, not both"))
        }
        (Some(Value::String(name)), None) => Some(
            Scenario::example_text(&name)
                .map_err(|e| in_context(e, "scenario.example"))?
                .to_string(),
        ),
        (None, Some(Value::String(path))) => {
            let path = base_dir.join(path);
            Some(std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?)
        }
        (Some(v), None) => return Err(bad("scenario.example", format!("`{v}` is not a name"))),
        (None, Some(v)) => return Err(bad("scenario.file", format!("`{v}` is not a path"))),
        (None, None) => None,
    };
    let Some(text) = base_text else {
        return Ok(table);
    };
    let mut base: Table = text
        .parse()
        .map_err(|e: toml::de::Error| bad("scenario", e.message().to_string()))?;
    merge(&mut base, table);
    Ok(base)
}

/// Merge `over` into `base`: tables key by key, everything else replaced. A `[flow]` with
/// another `type` replaces the base flow whole.
fn merge(base: &mut Table, over: Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(Value::Table(b)), Value::Table(o))
                if !(key == "flow" && o.contains_key("type")) =>
            {
                merge(b, o)
            }
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

/// Set `path` in `table`, creating tables on the way.
fn set_path(table: &mut Table, path: &[String], value: Value) {
    let (last, parents) = path.split_last().expect("a non-empty path");
    let mut t = table;
    for p in parents {
        let entry = t
            .entry(p.clone())
            .or_insert_with(|| Value::Table(Table::new()));
        if !entry.is_table() {
            *entry = Value::Table(Table::new());
        }
        t = entry.as_table_mut().expect("a table");
    }
    t.insert(last.clone(), value);
}

/// `extra`'s top-level keys before `base`, its tables after it.
#[cfg(test)]
pub(crate) fn around(base: &str, extra: &str) -> String {
    let at = extra
        .lines()
        .position(|l| l.starts_with('['))
        .unwrap_or(extra.lines().count());
    let lines: Vec<&str> = extra.lines().collect();
    format!(
        "{}\n{base}\n{}\n",
        lines[..at].join("\n"),
        lines[at..].join("\n")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const BASE: &str = "seeds = 2\nmethods = [\"corrsum\"]\n\
        [scenario]\nexample = \"uniform\"\nduration = \"40ms\"\n\
        sensor = { width = 96, height = 96, preset = \"ideal\" }\n";

    fn parse(extra: &str) -> Result<StudySpec> {
        StudySpec::from_toml(&around(BASE, extra), "t.toml", Path::new("."))
    }

    fn error(extra: &str) -> String {
        parse(extra).unwrap_err().to_string()
    }

    #[test]
    fn a_study_reads_its_base_overrides_and_axes() {
        let s = parse(
            "[process]\nwindow = [32]\n[sweep]\n\"scenario.flow.u\" = [0.5, 1, 2]\n\
             \"process.slab\" = [\"5ms\", \"10ms\"]\n\"sensor.refractory_us\" = [0.0, 50.0]\n",
        )
        .unwrap();
        assert_eq!(s.seeds, [1, 2]);
        assert_eq!(s.combinations(), 12);
        let keys: Vec<&str> = s.axes.iter().map(|a| a.key.as_str()).collect();
        assert_eq!(
            keys,
            ["process.slab", "scenario.flow.u", "sensor.refractory_us"]
        );
        let values = s.combination(5);
        assert_eq!(values[0], &Value::String("5ms".into()));
        assert_eq!(values[1], &Value::Integer(2));
        assert_eq!(values[2], &Value::Float(50.0));
        let scenario = s.scenario(&values, 7).unwrap();
        assert_eq!((scenario.seed, scenario.duration), (7, 40_000));
        assert_eq!(scenario.sensor.width, 96);
        assert_eq!(scenario.sensor_params().unwrap().refractory_us, 50.0);
        let sim = scenario.simulation().unwrap();
        assert_eq!(sim.velocity(1.0, 1.0, 0.0), (2.0, 0.0));
        let run = s.settings(&values, "corrsum").unwrap().resolve().unwrap();
        assert_eq!(run.corrsum.slab_us, 5_000);
        assert_eq!(run.process.passes[0].window, [32, 32]);
    }

    #[test]
    fn errors_name_the_key_and_the_problem() {
        for (extra, key, words) in [
            ("[sweep]\n\"scenario.flow.u\" = 3\n", "sweep.\"scenario.flow.u\"", "list"),
            ("[sweep]\n\"scenario.flow.u\" = []\n", "sweep.\"scenario.flow.u\"", "empty"),
            ("[sweep]\n\"camera.gain\" = [1]\n", "sweep.\"camera.gain\"", "camera"),
            ("[sweep]\n\"process.windw\" = [32]\n", "sweep.\"process.windw\"", "windw"),
            ("[sweep]\n\"process.method\" = [\"piv\"]\n", "sweep.\"process.method\"", "methods"),
            ("[sweep]\n\"scenario.seed\" = [1]\n", "sweep.\"scenario.seed\"", "seeds"),
            ("[sweep]\n\"process.slab\" = [\"5ms\", \"5ms\"]\n", "process.slab", "twice"),
            ("[sweep]\n\"process.window\" = [-3]\n", "window", "negative"),
            ("[sweep]\n\"sensor.treshold_on\" = [0.2]\n", "treshold_on", "sensor parameter"),
            ("[sweep]\n\"scenario.flow.u\" = [\"fast\"]\n", "scenario.flow.u", "fast"),
            ("[process]\nslab = \"ten\"\n", "slab", "ten"),
            ("[process]\ninput = \"a.raw\"\n", "process.input", "set by the study"),
            ("figures = [\"pie\"]\n", "figures", "pie"),
            ("metrics = [\"speed\"]\n", "metrics", "speed"),
            (
                "[[compare]]\nmetric = \"rms\"\nwhere = { \"process.slab\" = \"5ms\" }\npaper = 1\nsource = \"x\"\n",
                "compare[0].where",
                "not a swept key",
            ),
        ] {
            let e = error(extra);
            assert!(e.contains(key) && e.contains(words), "{extra}: {e}");
        }
        let e = StudySpec::from_toml("seeds = 0\n[scenario]\n", "t", Path::new(".")).unwrap_err();
        assert!(e.to_string().contains("seeds"), "{e}");
        let e = StudySpec::from_toml(
            "seeds = 1\nspeed = 2\n[scenario]\n",
            "t.toml",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("t.toml, line 2") && e.contains("speed"), "{e}");
        let e = StudySpec::from_toml(
            "seeds = 1\nmethods = [\"optical-flow\"]\n[scenario]\nexample = \"uniform\"\n",
            "t",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("methods") && e.contains("optical-flow"), "{e}");
        let e = StudySpec::from_toml(
            "seeds = 1\n[scenario]\nexample = \"tornado\"\n",
            "t",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("tornado") && e.contains("scenario.example"),
            "{e}"
        );
    }

    #[test]
    fn a_variant_is_a_method_with_its_own_settings() {
        let s = StudySpec::from_toml(
            &BASE.replace("[\"corrsum\"]", "[\"motion\", \"motion-grid\"]")
                .replace("[scenario]", "[variants.motion-grid]\nmethod = \"motion\"\nmotion-search = \"grid\"\n[scenario]"),
            "t",
            Path::new("."),
        )
        .unwrap();
        let grid = s.settings(&[], "motion-grid").unwrap();
        assert_eq!(grid.method, Method::Motion);
        assert_ne!(grid, s.settings(&[], "motion").unwrap());
        let e = StudySpec::from_toml(
            &BASE.replace(
                "[scenario]",
                "[variants.fast]\nmethod = \"motion\"\nspeed = 1\n[scenario]",
            ),
            "t",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("variants.fast.speed"), "{e}");
    }

    #[test]
    fn a_flow_of_another_type_replaces_the_base_flow() {
        let s =
            parse("[scenario.flow]\ntype = \"solid_body\"\ncentre = [48.0, 48.0]\nomega = 0.01\n")
                .unwrap();
        let flow = s.scenario["flow"].as_table().unwrap();
        assert!(!flow.contains_key("u"), "{flow:?}");
        s.scenario(&s.combination(0), 1).unwrap();
    }
}
