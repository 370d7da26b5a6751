//! The description of every setting, built from the one definition in
//! [`super::ProcessSettings`]: the command line's flags, the configuration file's keys, the
//! `ebiv init` template and the error messages all come from it (after ripgrep's flag
//! definitions).

use super::value::Kind;
use super::ProcessSettings;
use crate::error::{Error, Result};
use toml::Value;

/// One setting of [`ProcessSettings`].
pub struct Setting {
    /// The configuration key and long flag, kebab-case (`median-threshold`).
    pub key: &'static str,
    /// Other keys and flags accepted for it (`passes` for `window`).
    pub aliases: &'static [&'static str],
    /// A short flag, if any (`-o` for `output`).
    pub short: Option<char>,
    /// The heading it is listed under in `--help` and the template.
    pub group: &'static str,
    /// What it does, first sentence a summary (the field's doc comment).
    pub help: String,
    /// The placeholder of its value in `--help` (`DUR`, `PX[,PX..]`).
    pub value_name: &'static str,
    /// How the flag takes its value.
    pub kind: Kind,
    /// The recording, given as the first positional argument on the command line.
    pub positional: bool,
    pub(super) get: fn(&ProcessSettings) -> Option<Value>,
    pub(super) set: fn(&mut ProcessSettings, &Value) -> std::result::Result<(), String>,
    pub(super) set_texts: fn(&mut ProcessSettings, &[String]) -> std::result::Result<(), String>,
}

impl Setting {
    /// The first sentence of the help text.
    pub fn summary(&self) -> &str {
        // A full stop ends the sentence when a capital letter follows ("e.g. 40" goes on).
        let end = self.help.match_indices(". ").map(|(i, _)| i).find(|&i| {
            self.help[i + 2..]
                .chars()
                .next()
                .is_some_and(char::is_uppercase)
        });
        match end {
            Some(end) => &self.help[..end],
            None => self.help.trim_end_matches('.'),
        }
    }

    /// The default as a user types it (`10ms`, `64,40`, `true`), `None` when it depends
    /// on other settings.
    pub fn default_text(&self) -> Option<String> {
        self.default_value().map(|v| match v {
            Value::String(s) => s,
            Value::Array(items) => items
                .iter()
                .map(|i| match i {
                    Value::String(s) => s.clone(),
                    other => other.to_string(),
                })
                .collect::<Vec<_>>()
                .join(","),
            other => other.to_string(),
        })
    }

    /// The value in `settings`, `None` when unset.
    pub fn value(&self, settings: &ProcessSettings) -> Option<Value> {
        (self.get)(settings)
    }

    /// The default value, `None` when it depends on other settings (the help says how).
    pub fn default_value(&self) -> Option<Value> {
        (self.get)(&ProcessSettings::default())
    }

    /// Whether a switch is on by default, so that its flag is `--no-KEY`.
    pub fn on_by_default(&self) -> bool {
        self.kind == Kind::Switch && self.default_value() == Some(Value::Boolean(true))
    }

    /// The long flag: `--key`, or `--no-key` for a switch that is on by default.
    pub fn flag(&self) -> String {
        if self.on_by_default() {
            format!("no-{}", self.key)
        } else {
            self.key.to_string()
        }
    }

    fn matches(&self, key: &str) -> bool {
        self.key == key || self.aliases.contains(&key)
    }
}

/// The setting named `key` (or one of its aliases).
pub fn find(key: &str) -> Option<&'static Setting> {
    super::settings().iter().find(|s| s.matches(key))
}

/// Keys of the sections older configuration files had, with the key each became.
const RENAMED: &[(&str, &str)] = &[
    ("validation.median_threshold", "median-threshold"),
    ("validation.median_epsilon", "median-epsilon"),
    ("validation.min_events", "min-events"),
    ("validation.min_peak_ratio", "min-peak-ratio"),
    ("validation.max_velocity", "max-velocity"),
    ("corrsum.slab_us", "slab"),
    ("corrsum.tau_us", "tau"),
    ("corrsum.slices", "slices"),
    ("corrsum.kernel", "kernel"),
    ("corrsum.fit", "fit"),
    ("corrsum.weighting", "weighting"),
    ("corrsum.min_events", "estimator-min-events"),
    ("corrsum.search_radius_px", "search-radius"),
    ("corrsum.peak_smoothing_px", "peak-smoothing"),
    ("corrsum.subpixel_shift", "subpixel-shift"),
    ("motion.slab_us", "slab"),
    ("motion.objective", "objective"),
    ("motion.search_range", "search-range"),
    ("motion.coarse_step", "coarse-step"),
    ("motion.final_step", "final-step"),
    ("motion.min_events", "estimator-min-events"),
    ("motion.fit", "fit"),
    ("motion.search", "motion-search"),
];

impl ProcessSettings {
    /// Set the setting `key` from a TOML value; the error names the key.
    pub fn set(&mut self, key: &str, value: &Value) -> Result<()> {
        let setting = find(key).ok_or_else(|| unknown_key(key))?;
        (setting.set)(self, value).map_err(|m| Error::parameter(setting.key, m))
    }

    /// Set the setting `key` from the texts of its flag (a switch takes none and is turned
    /// on; `no-KEY` turns it off).
    pub fn set_flag(&mut self, key: &str, texts: &[String]) -> Result<()> {
        if let Some(setting) = key
            .strip_prefix("no-")
            .and_then(find)
            .filter(|s| s.kind == Kind::Switch)
        {
            return self.set(setting.key, &Value::Boolean(false));
        }
        let setting = find(key).ok_or_else(|| unknown_key(key))?;
        if setting.kind == Kind::Switch && texts.is_empty() {
            return self.set(setting.key, &Value::Boolean(true));
        }
        (setting.set_texts)(self, texts).map_err(|m| Error::parameter(setting.key, m))
    }

    /// Apply every key of a configuration table. Keys of the older `[validation]`,
    /// `[corrsum]` and `[motion]` sections still work; each gives a warning naming its new
    /// key, returned for the caller to print.
    pub fn apply_table(&mut self, table: &toml::Table) -> Result<Vec<String>> {
        let mut warnings = Vec::new();
        for (key, value) in table {
            match value {
                Value::Table(section) if find(key).is_none() => {
                    for (inner, value) in section {
                        let old = format!("{key}.{inner}");
                        let new = RENAMED
                            .iter()
                            .find(|(o, _)| *o == old)
                            .map(|(_, n)| *n)
                            .ok_or_else(|| {
                                Error::parameter(
                                    old.as_str(),
                                    format!(
                                        "unknown setting `{inner}` in section [{key}]; settings are top-level keys now{}",
                                        suggestion(inner)
                                    ),
                                )
                            })?;
                        // The old sections' bare numbers of µs are durations as they are.
                        self.set(new, value)?;
                        warnings.push(format!(
                            "[{key}] {inner} is now the top-level key `{new}`; this file still works, but write `{new} = …` above any section"
                        ));
                    }
                }
                _ => self.set(key, value)?,
            }
        }
        Ok(warnings)
    }

    /// Settings from the text of a configuration file, with warnings about old keys.
    pub fn from_toml_str(text: &str) -> Result<(ProcessSettings, Vec<String>)> {
        let table: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| Error::parameter("config", e.message().to_string()))?;
        let mut settings = ProcessSettings::default();
        let warnings = settings.apply_table(&table)?;
        Ok((settings, warnings))
    }

    /// Read a configuration file (see [`ProcessSettings::template`]) over these settings;
    /// the errors name the file.
    pub fn apply_file(&mut self, path: &std::path::Path) -> Result<Vec<String>> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let in_file = |e: Error| match e {
            Error::Parameter { name, message } => Error::Parameter {
                name,
                message: format!("{message} (in {})", path.display()),
            },
            other => other,
        };
        let table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            Error::parameter("config", format!("{}: {}", path.display(), e.message()))
        })?;
        self.apply_table(&table).map_err(in_file)
    }

    /// Every setting with a value, as `(key, TOML text)` pairs in schema order.
    pub fn to_pairs(&self) -> Vec<(&'static str, String)> {
        super::settings()
            .iter()
            .filter_map(|s| s.value(self).map(|v| (s.key, v.to_string())))
            .collect()
    }
}

fn unknown_key(key: &str) -> Error {
    Error::parameter(key, format!("unknown setting{}", suggestion(key)))
}

/// "; did you mean `window`?" for the known key closest to `key`, if one is close.
fn suggestion(key: &str) -> String {
    let wanted = key.replace('_', "-");
    if find(&wanted).is_some() {
        return format!("; did you mean `{wanted}`?");
    }
    super::settings()
        .iter()
        .map(|s| (edit_distance(&wanted, s.key), s.key))
        .filter(|&(d, k)| d <= 2.max(k.len() / 4))
        .min()
        .map(|(_, k)| format!("; did you mean `{k}`?"))
        .unwrap_or_default()
}

/// Levenshtein distance of two short strings.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (above + 1)
                .min(row[j] + 1)
                .min(diagonal + usize::from(ca != cb));
            diagonal = above;
        }
    }
    row[b.len()]
}

/// The configuration file `ebiv init` writes: every setting with its help as comments,
/// grouped as in `--help`; settings whose default depends on others are commented out.
pub fn template() -> String {
    let mut out = String::from(
        "# ebiv process configuration: `ebiv process --config THIS_FILE` (flags override keys).\n\
         # Every key is also a flag of `ebiv process` (--KEY). Durations take units (10ms, 250us,\n\
         # 1.5s); lengths are pixels; velocities px/ms. Image coordinates: x to the right, y down.\n",
    );
    let mut group = "";
    for s in super::settings() {
        if s.group != group {
            group = s.group;
            out.push_str(&format!("\n# ---- {group} ----\n"));
        }
        out.push('\n');
        for line in wrap(&s.help, 88) {
            out.push_str(&format!("# {line}\n"));
        }
        match s.default_value() {
            Some(v) => out.push_str(&format!("{} = {v}\n", s.key)),
            None => out.push_str(&format!("# {} = {}\n", s.key, s.value_name)),
        }
    }
    out
}

/// `text` in lines of at most `width` characters, broken at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for word in text.split_whitespace() {
        let line = lines.last_mut().expect("one line at least");
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > width {
            lines.push(word.to_string());
        } else {
            if !line.is_empty() {
                line.push(' ');
            }
            line.push_str(word);
        }
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::settings::{Duration, SlabLength};

    #[test]
    fn the_template_parses_to_the_defaults() {
        let (parsed, warnings) = ProcessSettings::from_toml_str(&template()).unwrap();
        assert!(warnings.is_empty());
        assert_eq!(parsed, ProcessSettings::default());
        // Every setting is in it, set or commented.
        for s in crate::settings::settings() {
            assert!(template().contains(&format!("{} = ", s.key)), "{}", s.key);
        }
    }

    #[test]
    fn unknown_keys_are_refused_with_a_suggestion() {
        let e = ProcessSettings::from_toml_str("windw = 32").unwrap_err();
        assert!(e.to_string().contains("did you mean `window`"), "{e}");
        let e = ProcessSettings::from_toml_str("median_threshold = 2.0").unwrap_err();
        assert!(e.to_string().contains("`median-threshold`"), "{e}");
        let e = ProcessSettings::from_toml_str("[validation]\nmedian_thresh = 2.0").unwrap_err();
        assert!(e.to_string().contains("median-threshold"), "{e}");
    }

    #[test]
    fn old_sections_still_work_and_name_the_new_key() {
        let text = "slab = \"8ms\"\n[validation]\nmedian_threshold = 3.0\nmin_events = 5\n\
                    [corrsum]\ntau_us = 2000\nkernel = \"fft\"\n[motion]\ncoarse_step = 0.5\n";
        let (s, warnings) = ProcessSettings::from_toml_str(text).unwrap();
        assert_eq!(s.median_threshold, 3.0);
        assert_eq!(s.min_events, 5);
        assert_eq!(s.tau.0, 2000);
        assert_eq!(s.slab, SlabLength::Fixed(Duration(8000)));
        assert_eq!(s.coarse_step, 0.5);
        assert_eq!(warnings.len(), 5);
        assert!(
            warnings.iter().any(|w| w.contains("`median-threshold`")),
            "{warnings:?}"
        );
    }

    #[test]
    fn flags_set_values_switches_and_negated_switches() {
        let mut s = ProcessSettings::default();
        s.set_flag("window", &["64,32".into()]).unwrap();
        s.set_flag("replace", &[]).unwrap();
        s.set_flag("no-secondary-peaks", &[]).unwrap();
        s.set_flag("passes", &["48".into()]).unwrap();
        assert_eq!(s.window.as_ref().unwrap().0, vec![48]);
        assert!(s.replace && !s.secondary_peaks);
        let e = s.set_flag("slab", &["ten".into()]).unwrap_err();
        assert!(e.to_string().contains("`slab`"), "{e}");
    }

    #[test]
    fn values_are_checked_where_they_are_set() {
        let mut s = ProcessSettings::default();
        for (key, bad) in [
            ("overlap", "1.0"),
            ("slab", "0"),
            ("slices", "0"),
            ("median-threshold", "0"),
            ("peak-smoothing", "-1"),
            ("pairs", "0"),
            ("mm-per-px", "0"),
            ("window", "0"),
        ] {
            let e = s.set_flag(key, &[bad.into()]).unwrap_err();
            assert!(e.to_string().contains(&format!("`{key}`")), "{key}: {e}");
        }
    }

    #[test]
    fn settings_round_trip_through_toml() {
        let mut s = ProcessSettings::default();
        s.set_flag("window", &["64,32,16".into()]).unwrap();
        s.set_flag("time", &["10ms:90ms:5ms".into()]).unwrap();
        s.set_flag("origin", &["0,720".into()]).unwrap();
        s.set_flag("images", &["a.png".into(), "b.png".into()])
            .unwrap();
        let text: String = s
            .to_pairs()
            .into_iter()
            .map(|(k, v)| format!("{k} = {v}\n"))
            .collect();
        let (back, _) = ProcessSettings::from_toml_str(&text).unwrap();
        assert_eq!(back, s);
    }
}
