//! Particle tracks as files: CSV (written track by track as they end), NumPy `.npz` and
//! NetCDF (one row per sample along the dimension `sample`). The columns, in this order:
//! `track_id,t_us,x,y,u,v,ax,ay` (px, px/ms, px/ms²), their standard uncertainties
//! `x_unc,y_unc,u_unc,v_unc,ax_unc,ay_unc`, the path's `curvature` (1/px), and the quality
//! of the fit: `events` in the fit window and `residual` (RMS distance of those events from
//! the path, px).

use super::netcdf::{Attribute, Dataset, Values, Variable};
use super::npz::{npy, npy_strings, write_npz};
use super::partial_path;
use crate::error::{Error, Result};
use crate::track::Track;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The columns: name, unit, description.
pub const TRACK_COLUMNS: [(&str, &str, &str); 17] = [
    ("track_id", "1", "track identity"),
    ("t_us", "us", "time of the sample, camera time"),
    ("x", "px", "position, image x (right)"),
    ("y", "px", "position, image y (down)"),
    ("u", "px/ms", "velocity x"),
    ("v", "px/ms", "velocity y (positive down)"),
    ("ax", "px/ms^2", "acceleration x"),
    ("ay", "px/ms^2", "acceleration y"),
    ("x_unc", "px", "standard uncertainty of x"),
    ("y_unc", "px", "standard uncertainty of y"),
    ("u_unc", "px/ms", "standard uncertainty of u"),
    ("v_unc", "px/ms", "standard uncertainty of v"),
    ("ax_unc", "px/ms^2", "standard uncertainty of ax"),
    ("ay_unc", "px/ms^2", "standard uncertainty of ay"),
    (
        "curvature",
        "1/px",
        "path curvature, positive turning clockwise on screen",
    ),
    ("events", "1", "events in the fit window"),
    (
        "residual",
        "px",
        "RMS distance of the window's events from the fitted path",
    ),
];

/// The samples of many tracks as columns.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrackTable {
    /// Track of each sample.
    pub track_id: Vec<u64>,
    /// Time, µs.
    pub t_us: Vec<i64>,
    /// The floating-point columns of [`TRACK_COLUMNS`] from `x` to `residual` (15), each
    /// one value per sample (`events` as a float).
    pub values: [Vec<f64>; 15],
}

impl TrackTable {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t_us.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t_us.is_empty()
    }

    /// The tracks of the table: one per run of consecutive samples of one identity (the
    /// counts of events and outliers, which the table does not hold, are 0).
    pub fn tracks(&self) -> Vec<Track> {
        let v = &self.values;
        let mut tracks: Vec<Track> = Vec::new();
        for (k, (&id, &t_us)) in self.track_id.iter().zip(&self.t_us).enumerate() {
            let sample = crate::track::TrackSample {
                t_us,
                x: v[0][k],
                y: v[1][k],
                u: v[2][k],
                v: v[3][k],
                ax: v[4][k],
                ay: v[5][k],
                unc: [v[6][k], v[7][k], v[8][k], v[9][k], v[10][k], v[11][k]],
                events: v[13][k] as u32,
                residual: v[14][k],
            };
            match tracks.last_mut() {
                Some(t) if t.id == id => {
                    t.span_us.1 = sample.t_us;
                    t.samples.push(sample);
                }
                _ => tracks.push(Track {
                    id,
                    samples: vec![sample],
                    events: 0,
                    outliers: 0,
                    span_us: (sample.t_us, sample.t_us),
                }),
            }
        }
        tracks
    }

    /// Append the samples of `track`.
    pub fn push(&mut self, track: &Track) {
        for s in &track.samples {
            self.track_id.push(track.id);
            self.t_us.push(s.t_us);
            for (column, value) in self.values.iter_mut().zip(sample_values(s)) {
                column.push(value);
            }
        }
    }
}

fn sample_values(s: &crate::track::TrackSample) -> [f64; 15] {
    [
        s.x,
        s.y,
        s.u,
        s.v,
        s.ax,
        s.ay,
        s.unc[0],
        s.unc[1],
        s.unc[2],
        s.unc[3],
        s.unc[4],
        s.unc[5],
        s.curvature(),
        s.events as f64,
        s.residual,
    ]
}

/// The CSV header line (without the newline).
pub fn track_csv_header() -> String {
    TRACK_COLUMNS.map(|c| c.0).join(",")
}

/// Which file a track output is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackFormat {
    /// `.csv`
    Csv,
    /// `.npz`
    Npz,
    /// `.nc`
    NetCdf,
}

impl TrackFormat {
    /// The format of `path` by its extension.
    pub fn of(path: &Path) -> Result<TrackFormat> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("csv") => Ok(TrackFormat::Csv),
            Some("npz") => Ok(TrackFormat::Npz),
            Some("nc") => Ok(TrackFormat::NetCdf),
            _ => Err(Error::parameter(
                "output",
                format!(
                    "{}: tracks are written as .csv, .npz or .nc",
                    path.display()
                ),
            )),
        }
    }
}

/// Writes tracks to a file as they come: CSV rows at once, the other formats at
/// [`TrackWriter::finish`]. The file appears, complete, only when finished; until then it
/// is `<path>.partial`, removed when the writer is dropped unfinished.
pub struct TrackWriter {
    path: PathBuf,
    format: TrackFormat,
    csv: Option<BufWriter<std::fs::File>>,
    table: TrackTable,
    finished: bool,
}

impl TrackWriter {
    /// A writer of `path` (format by extension).
    pub fn create(path: &Path) -> Result<TrackWriter> {
        let format = TrackFormat::of(path)?;
        let csv = if format == TrackFormat::Csv {
            let file = std::fs::File::create(partial_path(path)).map_err(|e| Error::io(path, e))?;
            let mut w = BufWriter::with_capacity(1 << 18, file);
            writeln!(w, "{}", track_csv_header()).map_err(|e| Error::io(path, e))?;
            Some(w)
        } else {
            None
        };
        Ok(TrackWriter {
            path: path.to_path_buf(),
            format,
            csv,
            table: TrackTable::default(),
            finished: false,
        })
    }

    /// Add one track.
    pub fn write(&mut self, track: &Track) -> Result<()> {
        match &mut self.csv {
            Some(w) => {
                for s in &track.samples {
                    let mut line = format!("{},{}", track.id, s.t_us);
                    for v in sample_values(s) {
                        use std::fmt::Write as _;
                        let _ = write!(line, ",{v}");
                    }
                    writeln!(w, "{line}").map_err(|e| Error::io(&self.path, e))?;
                }
                Ok(())
            }
            None => {
                self.table.push(track);
                Ok(())
            }
        }
    }

    /// Complete the file; `attributes` are written into NetCDF and NPZ files (CSV has
    /// only the columns).
    pub fn finish(mut self, attributes: &[(String, String)]) -> Result<()> {
        self.finished = true;
        match self.format {
            TrackFormat::Csv => {
                let w = self.csv.take().expect("a CSV writer");
                let file = w
                    .into_inner()
                    .map_err(|e| Error::io(&self.path, e.into_error()))?;
                file.sync_all().map_err(|e| Error::io(&self.path, e))?;
                drop(file);
                std::fs::rename(partial_path(&self.path), &self.path)
                    .map_err(|e| Error::io(&self.path, e))
            }
            TrackFormat::Npz => write_tracks_npz(&self.table, attributes, &self.path),
            TrackFormat::NetCdf => {
                let dataset = tracks_dataset(&self.table, attributes)?;
                super::write_dataset_netcdf(&dataset, &self.path)
            }
        }
    }
}

impl Drop for TrackWriter {
    fn drop(&mut self) {
        if !self.finished && self.csv.is_some() {
            self.csv = None;
            let _ = std::fs::remove_file(partial_path(&self.path));
        }
    }
}

/// The NetCDF layout of a track table: dimension `sample`, one variable per column (the
/// identity as `int`, the rest as `double`), units and descriptions as attributes.
pub fn tracks_dataset(table: &TrackTable, attributes: &[(String, String)]) -> Result<Dataset> {
    let ids: Vec<i32> = table
        .track_id
        .iter()
        .map(|&id| i32::try_from(id))
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| {
            Error::parameter(
                "output",
                "more than 2^31 tracks do not fit a NetCDF file; write .npz or .csv",
            )
        })?;
    let column = |k: usize, values: Values| Variable {
        name: TRACK_COLUMNS[k].0.into(),
        dims: vec!["sample".into()],
        values,
        attributes: vec![
            ("units".into(), Attribute::Text(TRACK_COLUMNS[k].1.into())),
            (
                "long_name".into(),
                Attribute::Text(TRACK_COLUMNS[k].2.into()),
            ),
        ],
    };
    let mut variables = vec![
        column(0, Values::I32(ids)),
        column(
            1,
            Values::F64(table.t_us.iter().map(|&t| t as f64).collect()),
        ),
    ];
    for (k, values) in table.values.iter().enumerate() {
        variables.push(column(k + 2, Values::F64(values.clone())));
    }
    let mut global = vec![(
        "software".into(),
        Attribute::Text(format!("ebiv {}", env!("CARGO_PKG_VERSION"))),
    )];
    global.extend(
        attributes
            .iter()
            .map(|(k, v)| (k.clone(), Attribute::Text(v.clone()))),
    );
    Ok(Dataset {
        dims: vec![("sample".into(), table.len())],
        variables,
        attributes: global,
    })
}

/// Write a track table as `.npz`: one array per column and `attributes` (`key=value`).
pub fn write_tracks_npz(
    table: &TrackTable,
    attributes: &[(String, String)],
    path: &Path,
) -> Result<()> {
    let n = table.len();
    let mut members: Vec<(&str, Vec<u8>)> = vec![
        ("track_id", npy(&table.track_id, &[n])),
        ("t_us", npy(&table.t_us, &[n])),
    ];
    for (k, values) in table.values.iter().enumerate() {
        members.push((TRACK_COLUMNS[k + 2].0, npy(values, &[n])));
    }
    let mut texts = vec![format!("software=ebiv {}", env!("CARGO_PKG_VERSION"))];
    texts.extend(attributes.iter().map(|(k, v)| format!("{k}={v}")));
    members.push(("attributes", npy_strings(&texts)));
    write_npz(path, &members)
}

/// Read a CSV file by its header: the rows as the numbers of the named `columns`, and each
/// row's line number.
fn read_csv_columns(path: &Path, columns: &[&str]) -> Result<Vec<(u64, Vec<f64>)>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let context = path.display().to_string();
    let parse_error = |line: u64, message: String| Error::Parse {
        context: context.clone(),
        line,
        message,
    };
    let text = String::from_utf8(bytes).map_err(|_| {
        parse_error(
            1,
            "not a text file (a CSV table of tracks was expected)".into(),
        )
    })?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .unwrap_or("")
        .split(',')
        .map(str::trim)
        .collect();
    let index: Vec<usize> = columns
        .iter()
        .map(|c| {
            header
                .iter()
                .position(|h| h == c)
                .ok_or_else(|| parse_error(1, format!("no column {c:?} in the header")))
        })
        .collect::<Result<_>>()?;
    let mut rows = Vec::new();
    for (n, line) in lines.enumerate() {
        let line_number = n as u64 + 2;
        if line.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').collect();
        let row = index
            .iter()
            .map(|&i| {
                let cell = cells.get(i).map(|c| c.trim()).unwrap_or("");
                cell.parse::<f64>().map_err(|_| {
                    parse_error(
                        line_number,
                        format!("{cell:?} is not a number in column {}", header[i]),
                    )
                })
            })
            .collect::<Result<Vec<f64>>>()?;
        rows.push((line_number, row));
    }
    Ok(rows)
}

/// `value` as a whole number within `range`, else an error naming the line and column.
fn whole(
    path: &Path,
    line: u64,
    column: &str,
    value: f64,
    range: std::ops::RangeInclusive<f64>,
) -> Result<f64> {
    if value.fract() == 0.0 && range.contains(&value) {
        Ok(value)
    } else {
        Err(Error::Parse {
            context: path.display().to_string(),
            line,
            message: format!(
                "{value} in column {column} is not a whole number in [{}, {}]",
                range.start(),
                range.end()
            ),
        })
    }
}

/// Read the tracks of a CSV file written by [`TrackWriter`] (samples of one track together).
pub fn read_tracks_csv(path: &Path) -> Result<Vec<Track>> {
    let names: Vec<&str> = TRACK_COLUMNS.iter().map(|c| c.0).collect();
    let rows = read_csv_columns(path, &names)?;
    let mut table = TrackTable::default();
    // Integers a double holds exactly.
    let exact = 9_007_199_254_740_992.0;
    for (line, r) in rows {
        table
            .track_id
            .push(whole(path, line, "track_id", r[0], 0.0..=exact)? as u64);
        table
            .t_us
            .push(whole(path, line, "t_us", r[1], -exact..=exact)? as i64);
        for (column, value) in table.values.iter_mut().zip(&r[2..]) {
            column.push(*value);
        }
    }
    Ok(table.tracks())
}

/// Read true particle paths as `ebiv simulate --tracks` writes them (id,t_us,x,y,z,u,v).
pub fn read_truth_tracks_csv(path: &Path) -> Result<Vec<crate::sim::simulation::TrackPoint>> {
    let rows = read_csv_columns(path, &["id", "t_us", "x", "y", "z", "u", "v"])?;
    rows.into_iter()
        .map(|(line, r)| {
            Ok(crate::sim::simulation::TrackPoint {
                id: whole(path, line, "id", r[0], 0.0..=9_007_199_254_740_992.0)? as u64,
                t_us: r[1],
                x: r[2],
                y: r[3],
                z: r[4],
                u: r[5],
                v: r[6],
            })
        })
        .collect()
}
