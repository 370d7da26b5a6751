//! The index of a recording: points where decoding can resume, each with the largest time
//! stamp before it and the decoder's state there (the EVT time bases, vector bases), so
//! that reading from a time in the middle of a RAW file starts close to it instead of
//! decoding everything before (`ebiv process --time`, `ebiv.dask` shards, `Recording.read`).
//!
//! An index is built by one pass over the file ([`build_index`], `ebiv index REC`) and kept
//! beside the recording as `REC.ebividx` (JSON), or, where that folder is not writable, in
//! the cache folder `$EBIV_INDEX_DIR` (default `$XDG_CACHE_HOME/ebiv/index` or
//! `~/.cache/ebiv/index`). [`super::open`] uses it when the file's size and modification
//! time still match; otherwise it is ignored. Formats whose decoders carry no resumable
//! state have no index (AEDAT 4 has its own table of packets).

use super::{EventReader, ReadOptions, ResumePoint};
use crate::error::{Error, Result};
use crate::event::EventBuffer;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Version of the index file's layout; other versions are ignored (and rebuilt).
const VERSION: u32 = 2;

/// Points are recorded at batch boundaries at least this many bytes apart.
pub const SPACING_BYTES: u64 = 1 << 20;

/// A point of the index.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IndexPoint {
    /// Largest time stamp of the events before the point, µs as decoded (before any
    /// Metavision shift); `None` when no event comes before it.
    pub time_before_us: Option<i64>,
    /// Where to resume, and how.
    pub resume: ResumePoint,
}

/// The index of one recording.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordingIndex {
    /// Layout version.
    pub version: u32,
    /// The file's format, as [`super::Format::name`] gives it.
    pub format: String,
    /// The file's size in bytes when indexed.
    pub file_size: u64,
    /// The file's modification time when indexed, ns since the Unix epoch.
    pub modified_ns: u64,
    /// The sensor size the file was decoded with (events outside it are dropped, so the
    /// decoder's state depends on it).
    pub geometry: Option<(u32, u32)>,
    /// The Metavision SDK time shift of the file ([`ReadOptions::metavision_time_shift`]).
    pub metavision_shift_us: Option<i64>,
    /// Events in the file.
    pub events: u64,
    /// Resume points in file order.
    pub points: Vec<IndexPoint>,
}

impl RecordingIndex {
    /// The last point whose events before all lie before `t_us`, beyond byte `after`.
    pub fn point_before(&self, t_us: i64, after: u64) -> Option<&IndexPoint> {
        self.points
            .iter()
            .take_while(|p| p.time_before_us.is_none_or(|t| t < t_us))
            .filter(|p| p.resume.offset > after)
            .last()
    }
}

/// Size and modification time of `path`, to tell whether an index still describes it.
fn stamp(path: &Path) -> Result<(u64, u64)> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    let modified = meta
        .modified()
        .ok()
        .and_then(|m| m.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos() as u64);
    Ok((meta.len(), modified))
}

/// Decode `path` once and record its resume points. An error for formats without them.
pub fn build_index(path: &Path, options: &ReadOptions) -> Result<RecordingIndex> {
    let options = ReadOptions {
        metavision_time_shift: false,
        ..options.clone()
    };
    let (file_size, modified_ns) = stamp(path)?;
    let mut reader = super::open_without_index(path, &options)?;
    let format = reader.metadata().format.name().to_string();
    let geometry = reader.metadata().geometry.map(|g| (g.width, g.height));
    let mut points = Vec::new();
    let mut batch = EventBuffer::new();
    let mut last: Option<i64> = None;
    let mut next_at = 0u64;
    loop {
        let Some(resume) = reader.inner_mut().resume_point() else {
            return Err(Error::Unsupported {
                context: path.display().to_string(),
                message: format!(
                    "{format} files have no index (only RAW EVT 2.0, 2.1 and 3.0 need one)"
                ),
            });
        };
        if resume.offset >= next_at {
            next_at = resume.offset + SPACING_BYTES;
            points.push(IndexPoint {
                time_before_us: last,
                resume,
            });
        }
        if !reader.read_batch(&mut batch)? {
            break;
        }
        if let Some(max) = batch.t.iter().max() {
            last = Some(last.map_or(*max, |l| l.max(*max)));
        }
    }
    Ok(RecordingIndex {
        version: VERSION,
        format,
        file_size,
        modified_ns,
        geometry,
        metavision_shift_us: reader.inner().metavision_time_shift(),
        events: reader.report().events,
        points,
    })
}

/// The index file beside `path`: `REC.ebividx`.
fn sidecar(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".ebividx");
    path.with_file_name(name)
}

/// The index file of `path` in the cache folder, named by a hash of its absolute path.
fn cached(path: &Path) -> Option<PathBuf> {
    let dir = std::env::var_os("EBIV_INDEX_DIR")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("XDG_CACHE_HOME").map(|d| PathBuf::from(d).join("ebiv/index")))
        .or_else(|| std::env::var_os("HOME").map(|d| PathBuf::from(d).join(".cache/ebiv/index")))?;
    let absolute = std::fs::canonicalize(path).ok()?;
    // FNV-1a: stable across runs and machines, unlike the standard library's hasher.
    let hash = absolute
        .to_string_lossy()
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
        });
    let stem = path.file_name().unwrap_or_default().to_string_lossy();
    Some(dir.join(format!("{stem}.{hash:016x}.ebividx")))
}

/// Write `index` of the recording at `path` beside it, or where that folder is not
/// writable, in the cache folder. Returns where it went.
pub fn write_index(path: &Path, index: &RecordingIndex) -> Result<PathBuf> {
    let text = serde_json::to_string(index).map_err(|e| Error::Write {
        what: "the index".into(),
        message: e.to_string(),
    })?;
    let beside = sidecar(path);
    if super::super::export::write_text(&beside, &text).is_ok() {
        return Ok(beside);
    }
    let cache = cached(path).ok_or_else(|| Error::Write {
        what: beside.display().to_string(),
        message: "the recording's folder is not writable and no cache folder is known; set EBIV_INDEX_DIR".into(),
    })?;
    if let Some(dir) = cache.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    super::super::export::write_text(&cache, &text)?;
    Ok(cache)
}

/// The index of `path` (format `format`, read on a sensor of `geometry`) if one is stored
/// and still describes the file. A file system without modification times has no index.
pub fn load_index(
    path: &Path,
    format: &str,
    geometry: Option<crate::event::Geometry>,
) -> Option<RecordingIndex> {
    find_index(path, format, geometry).map(|(index, _)| index)
}

/// [`load_index`], and the file it was read from.
fn find_index(
    path: &Path,
    format: &str,
    geometry: Option<crate::event::Geometry>,
) -> Option<(RecordingIndex, PathBuf)> {
    let (size, modified) = stamp(path).ok()?;
    if modified == 0 {
        return None;
    }
    let geometry = geometry.map(|g| (g.width, g.height));
    [Some(sidecar(path)), cached(path)]
        .into_iter()
        .flatten()
        .filter_map(|file| Some((std::fs::read_to_string(&file).ok()?, file)))
        .filter_map(|(text, file)| {
            Some((serde_json::from_str::<RecordingIndex>(&text).ok()?, file))
        })
        .find(|(ix, _)| {
            ix.version == VERSION
                && ix.format == format
                && ix.file_size == size
                && ix.modified_ns == modified
                && ix.geometry == geometry
        })
}

/// Whether the format of `path` has an index (RAW EVT 2.0, 2.1, 3.0).
pub fn indexable(path: &Path, options: &ReadOptions) -> Result<bool> {
    Ok(super::open_without_index(path, options)?
        .inner()
        .resume_point()
        .is_some())
}

/// An index found by [`ensure_index`], or built by it.
#[derive(Debug)]
pub struct EnsuredIndex {
    /// The index.
    pub index: RecordingIndex,
    /// Where it is stored.
    pub file: PathBuf,
    /// Whether it was built now (missing, stale, or `force`).
    pub built: bool,
}

/// The stored index of `path` if it still describes the file, else (or with `force`) a new
/// one built and stored now. An error for formats without an index ([`indexable`]).
pub fn ensure_index(path: &Path, options: &ReadOptions, force: bool) -> Result<EnsuredIndex> {
    let reader = super::open_without_index(path, options)?;
    let m = reader.metadata();
    if !force {
        if let Some((index, file)) = find_index(path, m.format.name(), m.geometry) {
            return Ok(EnsuredIndex {
                index,
                file,
                built: false,
            });
        }
    }
    let index = build_index(path, options)?;
    let file = write_index(path, &index)?;
    Ok(EnsuredIndex {
        index,
        file,
        built: true,
    })
}

impl EventReader {
    /// Skip by the index to the last point before `t_us` (as this reader delivers times,
    /// after any Metavision shift) past the current position; whether it jumped.
    pub(crate) fn jump_by_index(&mut self, t_us: i64) -> Result<bool> {
        let Some(index) = self.index.clone() else {
            return Ok(false);
        };
        // The index counts decoded times; a shift not learned yet is the index's.
        let shift = match (self.applies_metavision_shift(), self.shift_us()) {
            (false, _) => 0,
            (true, 0) => index.metavision_shift_us.unwrap_or(0),
            (true, known) => known,
        };
        let here = self.position().unwrap_or(0);
        match index.point_before(t_us.saturating_add(shift), here) {
            Some(point) => {
                self.inner_mut().resume(&point.resume)?;
                Ok(true)
            }
            None => Ok(false),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::event::Geometry;
    use crate::io::{write, Format};

    /// A recording of `n` events over 40 s (so that the EVT 3.0 time base loops twice),
    /// bursts of events at each time stamp so that vectors are used.
    fn recording(dir: &Path, format: Format, n: usize) -> PathBuf {
        let path = dir.join(format!("rec_{format:?}.raw"));
        let mut events = EventBuffer::new();
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        for i in 0..n {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let t = (i as i64 / 8) * 40_000_000 / (n as i64 / 8);
            events.push(
                t,
                (rng % 640) as u16,
                ((rng >> 20) % 480) as u16,
                (rng >> 40) as u8 & 1,
            );
        }
        let mut writer = write::create(&path, format, Some(Geometry::new(640, 480))).unwrap();
        writer.write(&events).unwrap();
        writer.finish().unwrap();
        path
    }

    fn events_from(path: &Path, t: i64, indexed: bool, shift: bool) -> (EventBuffer, bool) {
        let options = ReadOptions {
            metavision_time_shift: shift,
            ..ReadOptions::default()
        };
        let mut reader = if indexed {
            crate::io::open(path, &options).unwrap()
        } else {
            crate::io::open_without_index(path, &options).unwrap()
        };
        let used = reader.has_index();
        reader.skip_to(t).unwrap();
        let mut out = EventBuffer::new();
        let mut batch = EventBuffer::new();
        while reader.read_batch(&mut batch).unwrap() {
            out.extend_from(&batch);
        }
        (out, used)
    }

    #[test]
    fn seeking_by_the_index_reads_what_decoding_from_the_start_reads() {
        let dir = tempfile::tempdir().unwrap();
        for format in [Format::Evt3, Format::Evt2, Format::Evt21] {
            let path = recording(dir.path(), format, 1_200_000);
            let index = build_index(&path, &ReadOptions::default()).unwrap();
            assert!(
                index.points.len() >= 3,
                "{format:?}: {}",
                index.points.len()
            );
            assert_eq!(index.events, 1_200_000);
            let written = write_index(&path, &index).unwrap();
            assert_eq!(written, sidecar(&path));
            let mut targets = vec![
                0, 1, 9_999_999, 16_777_216, 20_000_000, 39_999_990, 50_000_000,
            ];
            // Just past each point: where a wrong shift or state would lose events.
            targets.extend(
                index
                    .points
                    .iter()
                    .filter_map(|p| p.time_before_us)
                    .map(|t| t + 1),
            );
            for t in targets {
                for shift in [false, true] {
                    let (plain, _) = events_from(&path, t, false, shift);
                    let (indexed, used) = events_from(&path, t, true, shift);
                    assert!(used);
                    assert_eq!(
                        plain, indexed,
                        "{format:?} at {t}, Metavision shift {shift}"
                    );
                }
            }
            // The index jumps: far into the file, the reader starts near the target.
            let mut reader = crate::io::open(&path, &ReadOptions::default()).unwrap();
            reader.skip_to(30_000_000).unwrap();
            assert!(reader.position().unwrap() > index.points[1].resume.offset);
        }
    }

    #[test]
    fn a_stale_or_foreign_index_is_ignored() {
        let dir = tempfile::tempdir().unwrap();
        let path = recording(dir.path(), Format::Evt3, 300_000);
        let index = build_index(&path, &ReadOptions::default()).unwrap();
        write_index(&path, &index).unwrap();
        let g = Some(Geometry::new(640, 480));
        assert!(load_index(&path, "Prophesee RAW EVT 3.0", g).is_some());
        assert!(load_index(&path, "Prophesee RAW EVT 2.0", g).is_none());
        assert!(load_index(
            &path,
            "Prophesee RAW EVT 3.0",
            Some(Geometry::new(640, 240))
        )
        .is_none());
        // The file changes: the index no longer describes it.
        let mut bytes = std::fs::read(&path).unwrap();
        bytes.extend_from_slice(&[0, 0x80]);
        std::fs::write(&path, bytes).unwrap();
        assert!(load_index(&path, "Prophesee RAW EVT 3.0", g).is_none());
        assert!(!crate::io::open(&path, &ReadOptions::default())
            .unwrap()
            .has_index());
        // A damaged state is an error naming the index, not a panic.
        let mut reader = crate::io::open(&path, &ReadOptions::default()).unwrap();
        let good = index.points[1].resume.clone();
        let bad = [
            ResumePoint {
                offset: good.offset,
                state: vec![1, 2],
            },
            ResumePoint {
                offset: good.offset + 1,
                state: good.state.clone(),
            },
            ResumePoint {
                offset: u64::MAX - 1,
                state: good.state.clone(),
            },
            ResumePoint {
                offset: 0,
                state: good.state.clone(),
            },
            ResumePoint {
                offset: good.offset,
                state: good.state.iter().map(|_| i64::MAX).collect(),
            },
        ];
        for point in &bad {
            let e = reader.inner_mut().resume(point).unwrap_err().to_string();
            assert!(e.contains("index"), "{point:?}: {e}");
        }
        // The reader is where it was and still reads the whole file.
        let mut all = EventBuffer::new();
        let mut batch = EventBuffer::new();
        while reader.read_batch(&mut batch).unwrap() {
            all.extend_from(&batch);
        }
        assert_eq!(all.len(), 300_000);
    }

    #[test]
    fn formats_without_resumable_state_have_no_index() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("e.csv");
        std::fs::write(&path, "t,x,y,p\n1,2,3,1\n").unwrap();
        let e = build_index(&path, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("no index"), "{e}");
        assert!(!indexable(&path, &ReadOptions::default()).unwrap());
        assert!(ensure_index(&path, &ReadOptions::default(), false).is_err());
    }
}
