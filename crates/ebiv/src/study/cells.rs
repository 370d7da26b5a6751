//! The cells of a study (one combination of swept values × method × seed), their keys, and
//! the store of finished cells in the output directory that makes a study resumable.
//!
//! A cell's key is a hash of everything that determines its result: the scenario table with
//! the swept values and the seed, every `ebiv process` setting (defaults included), the
//! method, the field count and margin, [`FORMAT`] and [`CODE_VERSION`]. A rerun finds a finished cell by its
//! key and skips it; a changed study has other keys and so never reuses a stale result.
//! Each finished cell is one file `cells/KEY.toml` (its metrics) beside `cells/KEY.csv` (its
//! valid vectors, for the figures), both written through temporary files, the metrics last:
//! a cell counts as finished once its metrics file exists, whatever interrupted the run.

use super::metrics::VectorRecord;
use super::spec::StudySpec;
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};
use toml::{Table, Value};

/// Version of the cell files and of what a cell computes, raised whenever a cell's result
/// would change (a metric, an estimator, its uncertainty); part of every key with the
/// version of ebiv ([`CODE_VERSION`]), so that cells of another version are recomputed.
pub const FORMAT: &str = "ebiv-study-cell-3";

/// The version of ebiv that computes the cells: a study rerun by another version of ebiv
/// recomputes every cell rather than mix results of two versions.
pub const CODE_VERSION: &str = env!("CARGO_PKG_VERSION");

/// One cell of a study.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// Index of its combination of swept values ([`StudySpec::combination`]).
    pub combination: usize,
    /// The method.
    pub method: String,
    /// The scenario seed.
    pub seed: u64,
    /// The key of its result: 16 hexadecimal digits.
    pub key: String,
    /// The key of its recording (scenario and seed): cells sharing it share one simulation.
    pub recording: String,
}

/// Every cell of `spec`: combinations in order, then methods, then seeds.
pub fn cells(spec: &StudySpec) -> Result<Vec<Cell>> {
    let mut all = Vec::new();
    for c in 0..spec.combinations() {
        let values = spec.combination(c);
        for method in &spec.methods {
            let settings = spec.settings(&values, method)?;
            let pairs: Vec<String> = settings
                .to_pairs()
                .into_iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect();
            for &seed in &spec.seeds {
                let scenario = canonical_table(&spec.scenario_table(&values, seed));
                let recording = hex(fnv1a(scenario.as_bytes()));
                let all_of_it = format!(
                    "{FORMAT} {CODE_VERSION}\nscenario {scenario}\nprocess {}\nfields {}\nmargin {}\n",
                    pairs.join(";"),
                    spec.fields,
                    spec.margin_us
                );
                all.push(Cell {
                    combination: c,
                    method: method.clone(),
                    seed,
                    key: hex(fnv1a(all_of_it.as_bytes())),
                    recording,
                });
            }
        }
    }
    Ok(all)
}

/// 64-bit FNV-1a (Fowler, Noll & Vo): a stable hash, the same on every machine and version.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

fn hex(h: u64) -> String {
    format!("{h:016x}")
}

/// A TOML table as one line with its keys sorted at every level, so that equal tables give
/// equal text however they were written.
pub fn canonical_table(table: &Table) -> String {
    let mut out = String::new();
    canonical(&Value::Table(table.clone()), &mut out);
    out
}

fn canonical(value: &Value, out: &mut String) {
    match value {
        Value::Table(t) => {
            let mut keys: Vec<&String> = t.keys().collect();
            keys.sort();
            out.push('{');
            for k in keys {
                out.push_str(&format!("{k:?}="));
                canonical(&t[k], out);
                out.push(',');
            }
            out.push('}');
        }
        Value::Array(items) => {
            out.push('[');
            for v in items {
                canonical(v, out);
                out.push(',');
            }
            out.push(']');
        }
        // Integers and floats of the same value set the same parameter.
        Value::Integer(i) => out.push_str(&format!("{:?}", *i as f64)),
        Value::Float(f) => out.push_str(&format!("{f:?}")),
        other => out.push_str(&other.to_string()),
    }
}

/// What a finished cell measured, as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct CellResult {
    /// The cell's key.
    pub key: String,
    /// Its metrics in the order of [`super::metrics::METRICS`]; empty when it could not run.
    pub metrics: Vec<(String, f64)>,
    /// Why it could not run (the library's message), if so.
    pub error: Option<String>,
}

impl CellResult {
    /// The value of `metric`, NaN when absent.
    pub fn get(&self, metric: &str) -> f64 {
        self.metrics
            .iter()
            .find(|(m, _)| m == metric)
            .map_or(f64::NAN, |m| m.1)
    }
}

/// The finished cells in `DIR/cells/`.
#[derive(Debug, Clone)]
pub struct CellStore {
    dir: PathBuf,
}

impl CellStore {
    /// The store of the output directory `out`, created if needed.
    pub fn open(out: &Path) -> Result<CellStore> {
        let dir = out.join("cells");
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        Ok(CellStore { dir })
    }

    fn metrics_path(&self, key: &str) -> PathBuf {
        self.dir.join(format!("{key}.toml"))
    }

    fn vectors_path(&self, key: &str) -> PathBuf {
        self.dir.join(format!("{key}.csv"))
    }

    /// The stored result of `cell`, if it is finished and readable (an unreadable file is
    /// taken as unfinished, and the cell is computed again).
    pub fn load(&self, cell: &Cell) -> Option<CellResult> {
        let text = std::fs::read_to_string(self.metrics_path(&cell.key)).ok()?;
        let table: Table = text.parse().ok()?;
        if table.get("key")?.as_str()? != cell.key {
            return None;
        }
        let metrics = table
            .get("metrics")
            .and_then(Value::as_table)
            .map(|m| {
                super::metrics::METRICS
                    .iter()
                    .filter_map(|(name, ..)| {
                        let v = match m.get(*name)? {
                            Value::Float(f) => *f,
                            Value::Integer(i) => *i as f64,
                            _ => return None,
                        };
                        Some((name.to_string(), v))
                    })
                    .collect()
            })
            .unwrap_or_default();
        Some(CellResult {
            key: cell.key.clone(),
            metrics,
            error: table
                .get("error")
                .and_then(Value::as_str)
                .map(str::to_string),
        })
    }

    /// Store a finished cell: its valid vectors first, then its metrics (which mark it
    /// finished), with a description of the cell for a person reading the file.
    pub fn save(
        &self,
        spec: &StudySpec,
        cell: &Cell,
        result: &CellResult,
        vectors: &[VectorRecord],
    ) -> Result<()> {
        let mut csv = String::from("t_us,x_px,y_px,u,v,u_true,v_true\n");
        for r in vectors {
            csv.push_str(&format!(
                "{},{},{},{},{},{},{}\n",
                r.t_us, r.x, r.y, r.u, r.v, r.u_true, r.v_true
            ));
        }
        crate::export::write_text(&self.vectors_path(&cell.key), &csv)?;
        let mut t = Table::new();
        t.insert("key".into(), Value::String(cell.key.clone()));
        t.insert("method".into(), Value::String(cell.method.clone()));
        t.insert("seed".into(), Value::Integer(cell.seed as i64));
        let mut values = Table::new();
        for (axis, v) in spec.axes.iter().zip(spec.combination(cell.combination)) {
            values.insert(axis.key.clone(), v.clone());
        }
        t.insert("values".into(), Value::Table(values));
        if let Some(e) = &result.error {
            t.insert("error".into(), Value::String(e.clone()));
        }
        let metrics: Table = result
            .metrics
            .iter()
            .map(|(k, v)| (k.clone(), Value::Float(*v)))
            .collect();
        t.insert("metrics".into(), Value::Table(metrics));
        let text = toml::to_string(&t).map_err(|e| Error::Write {
            what: self.metrics_path(&cell.key).display().to_string(),
            message: e.to_string(),
        })?;
        crate::export::write_text(&self.metrics_path(&cell.key), &text)
    }

    /// The stored valid vectors of a finished cell.
    pub fn vectors(&self, key: &str) -> Result<Vec<VectorRecord>> {
        let path = self.vectors_path(key);
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let mut out = Vec::new();
        for (n, line) in text.lines().enumerate().skip(1) {
            let f: Vec<f64> = line.split(',').filter_map(|s| s.parse().ok()).collect();
            if f.len() != 7 {
                return Err(Error::corrupt(
                    path.display().to_string(),
                    n as u64 + 1,
                    "expected 7 numbers on the line",
                ));
            }
            out.push(VectorRecord {
                t_us: f[0] as i64,
                x: f[1],
                y: f[2],
                u: f[3],
                v: f[4],
                u_true: f[5],
                v_true: f[6],
            });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(extra: &str) -> StudySpec {
        let base =
            "seeds = 2\nmethods = [\"corrsum\", \"motion\"]\n[scenario]\nexample = \"uniform\"\n\
             sensor = { width = 96, height = 96, preset = \"ideal\" }\n";
        let text = super::super::spec::around(base, extra);
        StudySpec::from_toml(&text, "t", Path::new(".")).unwrap()
    }

    #[test]
    fn keys_are_stable_and_follow_every_setting() {
        let base = spec("[sweep]\n\"process.slab\" = [\"5ms\", \"10ms\"]\n");
        let a = cells(&base).unwrap();
        assert_eq!(a.len(), 8);
        assert_eq!(a, cells(&base).unwrap(), "the same study, the same keys");
        let keys: std::collections::HashSet<&str> = a.iter().map(|c| c.key.as_str()).collect();
        assert_eq!(keys.len(), 8, "every cell its own key");
        // Cells differing only in method or slab share their recording; seeds do not.
        assert_eq!(a[0].recording, a[2].recording);
        assert_eq!(a[0].recording, a[4].recording);
        assert_ne!(a[0].recording, a[1].recording);
        // The same value written differently, or reached another way, keeps the key.
        let same = spec(
            "[process]\nslab = \"10ms\"\n[sweep]\n\"process.slab\" = [\"5ms\", \"10000us\"]\n",
        );
        assert_eq!(cells(&same).unwrap(), a);
        let float = StudySpec {
            scenario: {
                let mut s = base.scenario.clone();
                s["particles"]["density"] = Value::Integer(0);
                s
            },
            ..base.clone()
        };
        let int = StudySpec {
            scenario: {
                let mut s = base.scenario.clone();
                s["particles"]["density"] = Value::Float(0.0);
                s
            },
            ..base.clone()
        };
        assert_eq!(cells(&float).unwrap(), cells(&int).unwrap());
        // Any other setting, scenario value, field count or seed changes it.
        for changed in [
            spec("[process]\nmedian-threshold = 3.0\n[sweep]\n\"process.slab\" = [\"5ms\", \"10ms\"]\n"),
            spec("[scenario.particles]\ndensity = 0.01\n[sweep]\n\"process.slab\" = [\"5ms\", \"10ms\"]\n"),
            spec("fields = 2\n[sweep]\n\"process.slab\" = [\"5ms\", \"10ms\"]\n"),
        ] {
            let b = cells(&changed).unwrap();
            assert!(a.iter().zip(&b).all(|(x, y)| x.key != y.key));
        }
        // FNV-1a's published test vectors: the keys of stored cells stay valid.
        assert_eq!(hex(fnv1a(b"")), "cbf29ce484222325");
        assert_eq!(hex(fnv1a(b"a")), "af63dc4c8601ec8c");
    }

    #[test]
    fn a_stored_cell_reads_back_and_a_damaged_one_counts_as_unfinished() {
        let s = spec("");
        let all = cells(&s).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let store = CellStore::open(dir.path()).unwrap();
        assert!(store.load(&all[0]).is_none());
        let result = CellResult {
            key: all[0].key.clone(),
            metrics: vec![("rms".into(), 0.25), ("dvr".into(), f64::NAN)],
            error: None,
        };
        let v = VectorRecord {
            t_us: 5,
            x: 1.0,
            y: 2.0,
            u: 0.5,
            v: -0.25,
            u_true: 0.5,
            v_true: 0.0,
        };
        store.save(&s, &all[0], &result, &[v]).unwrap();
        let back = store.load(&all[0]).unwrap();
        assert_eq!(back.get("rms"), 0.25);
        assert!(back.get("dvr").is_nan() && back.error.is_none());
        assert_eq!(store.vectors(&all[0].key).unwrap(), [v]);
        assert!(store.load(&all[1]).is_none());
        std::fs::write(store.metrics_path(&all[0].key), "key = ").unwrap();
        assert!(store.load(&all[0]).is_none());
    }
}
