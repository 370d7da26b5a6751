//! The small datasets beside the events of an HDF5 file: the root attributes, DSEC's
//! `t_offset`, the seek indexes (`/CD/indexes`, `ms_to_idx`) and the trigger edges.

use super::super::npy::{gather, Kind, Num};
use super::{check_record, one_dimensional, scalar_of, MAX_INDEX_ENTRIES, MAX_TRIGGERS};
use crate::error::{Error, Result};
use crate::event::Trigger;
use crate::io::DecodeReport;
use hdf5_reader::{dtype_element_size, Dataset, Datatype, Hdf5File};

/// An integer value, `None` for a float or one outside `i64`.
fn integer(v: Num) -> Option<i64> {
    match v {
        Num::I(i) => Some(i),
        Num::U(u) => i64::try_from(u).ok(),
        Num::F(_) => None,
    }
}

/// A sorted table from time to the first event at or after it, to seek by.
#[derive(Debug, Clone, Default)]
pub(super) struct SeekTable {
    /// (time, event index), both rising.
    pub(super) entries: Vec<(i64, u64)>,
}

impl SeekTable {
    /// The index of an event at or before the first event at or after `t`.
    pub(super) fn start_for(&self, t: i64) -> Option<u64> {
        let k = self.entries.partition_point(|&(time, _)| time <= t);
        k.checked_sub(1).map(|k| self.entries[k].1)
    }
}

/// The root attributes as header entries: strings as stored, numbers written out.
pub(super) fn root_attributes(file: &Hdf5File) -> Vec<(String, String)> {
    let Ok(root) = file.root_group() else {
        return Vec::new();
    };
    let mut entries: Vec<(String, String)> = root
        .attributes()
        .unwrap_or_default()
        .into_iter()
        .filter_map(|a| {
            let value = a.read_string().ok().or_else(|| {
                let v = a.read_as_f64().ok()?;
                Some(if v.fract() == 0.0 && v.abs() < 9e15 {
                    format!("{}", v as i64)
                } else {
                    format!("{v}")
                })
            })?;
            Some((a.name.clone(), value))
        })
        .collect();
    entries.sort();
    entries
}

/// A scalar integer dataset (DSEC `t_offset`).
pub(super) fn scalar_i64(file: &Hdf5File, path: &str) -> Option<i64> {
    let d = file.dataset(path).ok()?;
    if d.num_elements().ok()? != 1 {
        return None;
    }
    let scalar = scalar_of(d.dtype())?;
    let bytes = d.read_raw_bytes().ok()?;
    let mut raw = Vec::new();
    gather(&bytes, scalar.size, 0, scalar, &mut raw);
    integer(scalar.num(*raw.first()?))
}

/// The values of a small 1-D integer dataset, or of one field of a compound one.
fn integer_column(d: &Dataset, field: Option<&str>, limit: u64) -> Option<Vec<i64>> {
    let n = one_dimensional(d, "", "").ok()?;
    check_record(d, "", "").ok()?;
    if n > limit {
        return None;
    }
    let (offset, scalar) = match (d.dtype(), field) {
        (Datatype::Compound { fields, .. }, Some(name)) => {
            let f = fields.iter().find(|f| f.name == name)?;
            (f.byte_offset as usize, scalar_of(&f.datatype)?)
        }
        (dtype, None) => (0, scalar_of(dtype)?),
        _ => return None,
    };
    if scalar.kind == Kind::Float {
        return None;
    }
    let size = dtype_element_size(d.dtype()).ok()?;
    let bytes = d.read_raw_bytes().ok()?;
    let mut raw = Vec::new();
    gather(&bytes, size, offset, scalar, &mut raw);
    raw.into_iter().map(|v| integer(scalar.num(v))).collect()
}

/// The seek table of `/CD/indexes`: rows `(id, ts)` with `ts` relative to the first event
/// and the `offset` attribute `−t_first` (formats.md §6.2). An index that is not rising in
/// both is not used (a warning says so).
pub(super) fn metavision_index(
    file: &Hdf5File,
    context: &str,
    report: &mut DecodeReport,
) -> SeekTable {
    let Ok(d) = file.dataset("/CD/indexes") else {
        return SeekTable::default();
    };
    let offset = d.attribute("offset").ok().and_then(|a| {
        a.read_string()
            .ok()
            .and_then(|s| s.trim().parse::<i64>().ok())
    });
    let (Some(ids), Some(ts), Some(offset)) = (
        integer_column(&d, Some("id"), MAX_INDEX_ENTRIES),
        integer_column(&d, Some("ts"), MAX_INDEX_ENTRIES),
        offset,
    ) else {
        return SeekTable::default();
    };
    let entries: Vec<(i64, u64)> = ts
        .iter()
        .zip(&ids)
        .filter(|(&t, _)| t >= 0)
        .filter_map(|(&t, &id)| Some((t.checked_sub(offset)?, u64::try_from(id).ok()?)))
        .collect();
    checked_table(entries, context, "/CD/indexes", report)
}

/// The seek table of a DSEC `ms_to_idx`: entry `k` is the first event at or after `k` ms.
pub(super) fn dsec_index(file: &Hdf5File, t_offset: i64) -> SeekTable {
    let Some(ids) = file
        .dataset("ms_to_idx")
        .ok()
        .and_then(|d| integer_column(&d, None, MAX_INDEX_ENTRIES))
    else {
        return SeekTable::default();
    };
    let entries = ids
        .iter()
        .enumerate()
        .filter_map(|(k, &id)| {
            let t = (k as i64).checked_mul(1000)?.checked_add(t_offset)?;
            Some((t, u64::try_from(id).ok()?))
        })
        .collect();
    checked_table(entries, "", "ms_to_idx", &mut DecodeReport::default())
}

fn checked_table(
    entries: Vec<(i64, u64)>,
    context: &str,
    name: &str,
    report: &mut DecodeReport,
) -> SeekTable {
    let rising = entries
        .windows(2)
        .all(|w| w[0].0 <= w[1].0 && w[0].1 <= w[1].1);
    if rising {
        SeekTable { entries }
    } else {
        report.warn(format!(
            "{context}: {name} is not in time order and is not used to seek"
        ));
        SeekTable::default()
    }
}

/// The trigger edges of `/EXT_TRIGGER/events` (`p`, `t`, `id`), in file order.
pub(super) fn read_triggers(
    file: &Hdf5File,
    context: &str,
    report: &mut DecodeReport,
) -> Result<Vec<Trigger>> {
    let Ok(d) = file.dataset("/EXT_TRIGGER/events") else {
        return Ok(Vec::new());
    };
    let n = one_dimensional(&d, "/EXT_TRIGGER/events", context)?;
    if n == 0 {
        return Ok(Vec::new());
    }
    if n > MAX_TRIGGERS {
        return Err(Error::unsupported(
            context,
            format!("/EXT_TRIGGER/events holds {n} edges; at most {MAX_TRIGGERS} are read"),
        ));
    }
    let column = |name| {
        integer_column(&d, Some(name), MAX_TRIGGERS).ok_or_else(|| {
            Error::unsupported(
                context,
                format!("/EXT_TRIGGER/events has no integer field `{name}` (or cannot be read)"),
            )
        })
    };
    let (p, t, id) = (column("p")?, column("t")?, column("id")?);
    let mut triggers = Vec::with_capacity(t.len());
    for (k, ((&p, &t), &id)) in p.iter().zip(&t).zip(&id).enumerate() {
        match u8::try_from(id) {
            Ok(channel) => triggers.push(Trigger {
                t,
                channel,
                value: u8::from(p > 0),
            }),
            Err(_) => {
                report.malformed += 1;
                report.warn(format!(
                    "{context}: trigger {k} skipped: channel {id} is not 0–255"
                ));
            }
        }
    }
    Ok(triggers)
}
