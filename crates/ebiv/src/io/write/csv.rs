//! CSV event writer (formats.md §11): a `t,x,y,p` header line, then, when the sensor size is
//! known, a comment line `# geometry: 640x480`, then one event per line in the order given,
//! t in integer µs, p as 0/1. Triggers are not stored.
//!
//! ebiv's text reader takes the sensor size from the comment, so that a recording converted
//! to CSV and back keeps it. The comment follows the header so that readers which take the
//! first line as the column names still find them: `numpy.loadtxt(path, delimiter=',',
//! skiprows=1)` and `numpy.genfromtxt(path, delimiter=',', names=True)` skip `#` lines by
//! default, pandas with `read_csv(path, comment='#')`. Read back exactly by ebiv.

use super::{AtomicFile, EventWriter};
use crate::error::Result;
use crate::event::{EventBuffer, Geometry};
use std::io::Write;
use std::path::Path;

/// Bytes collected before they are handed to the file.
const FLUSH_BYTES: usize = 1 << 20;

/// Streaming CSV writer.
pub(crate) struct CsvWriter {
    file: AtomicFile,
    buf: Vec<u8>,
}

impl CsvWriter {
    /// Start writing `path` (through a temporary file renamed by `finish`), with the sensor
    /// size `geometry` in a comment line when given.
    pub fn create(path: &Path, geometry: Option<Geometry>) -> Result<Self> {
        let mut buf = Vec::with_capacity(FLUSH_BYTES + 64);
        buf.extend_from_slice(b"t,x,y,p\n");
        if let Some(g) = geometry {
            buf.extend_from_slice(format!("# geometry: {}x{}\n", g.width, g.height).as_bytes());
        }
        Ok(CsvWriter {
            file: AtomicFile::create(path)?,
            buf,
        })
    }

    fn flush_buf(&mut self) -> Result<()> {
        let io = self.file.writer().write_all(&self.buf);
        io.map_err(|e| self.file.err(e))?;
        self.buf.clear();
        Ok(())
    }
}

/// Two-digit strings "00".."99", for formatting two digits per step.
const PAIRS: &[u8; 200] = b"0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// Append the decimal digits of `v`.
#[inline]
fn push_u64(out: &mut Vec<u8>, mut v: u64) {
    let mut tmp = [0u8; 20];
    let mut i = tmp.len();
    while v >= 100 {
        let pair = (v % 100) as usize * 2;
        v /= 100;
        i -= 2;
        tmp[i..i + 2].copy_from_slice(&PAIRS[pair..pair + 2]);
    }
    if v >= 10 {
        let pair = v as usize * 2;
        i -= 2;
        tmp[i..i + 2].copy_from_slice(&PAIRS[pair..pair + 2]);
    } else {
        i -= 1;
        tmp[i] = b'0' + v as u8;
    }
    out.extend_from_slice(&tmp[i..]);
}

/// Append the decimal form of `v` with a leading `-` when negative.
#[inline]
fn push_i64(out: &mut Vec<u8>, v: i64) {
    if v < 0 {
        out.push(b'-');
    }
    push_u64(out, v.unsigned_abs());
}

impl EventWriter for CsvWriter {
    fn write(&mut self, events: &EventBuffer) -> Result<()> {
        let n = events.len();
        let columns = events.t.iter().zip(&events.x).zip(&events.y).zip(&events.p);
        for (k, (((&t, &x), &y), &p)) in columns.enumerate() {
            push_i64(&mut self.buf, t);
            self.buf.push(b',');
            push_u64(&mut self.buf, x as u64);
            self.buf.push(b',');
            push_u64(&mut self.buf, y as u64);
            self.buf.push(b',');
            self.buf.push(if p != 0 { b'1' } else { b'0' });
            self.buf.push(b'\n');
            if self.buf.len() >= FLUSH_BYTES && k + 1 < n {
                self.flush_buf()?;
            }
        }
        if self.buf.len() >= FLUSH_BYTES {
            self.flush_buf()?;
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        self.flush_buf()?;
        self.file.commit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{self, Format, ReadOptions};

    #[test]
    fn integers_format_like_std() {
        for v in [
            0i64,
            1,
            9,
            10,
            99,
            100,
            101,
            12345,
            -1,
            -100,
            i64::MAX,
            i64::MIN,
            i64::MIN + 1,
        ] {
            let mut out = Vec::new();
            push_i64(&mut out, v);
            assert_eq!(String::from_utf8(out).unwrap(), v.to_string());
        }
    }

    fn edge_events() -> EventBuffer {
        let mut e = EventBuffer::new();
        e.push(i64::MIN, 0, 0, 0);
        e.push(-1, 65535, 65535, 1);
        e.push(0, 1, 2, 1);
        e.push(3811, 96, 133, 0);
        e.push(i64::MAX, 65535, 0, 1);
        e
    }

    #[test]
    fn round_trip_through_the_text_reader() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("events.csv");
        let events = edge_events();
        let mut w: Box<dyn EventWriter> = Box::new(CsvWriter::create(&path, None).unwrap());
        w.write(&events).unwrap();
        w.write(&EventBuffer::new()).unwrap();
        w.write(&events).unwrap();
        w.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("t,x,y,p\n-9223372036854775808,0,0,0\n-1,65535,65535,1\n"));
        let rec = io::read_all(&path, &ReadOptions::default()).unwrap();
        assert_eq!(rec.metadata.format, Format::Text);
        let mut twice = events.clone();
        twice.extend_from(&events);
        assert_eq!(rec.events, twice);
        assert!(rec.report.warnings.is_empty(), "{:?}", rec.report);
        assert_eq!(rec.report.malformed + rec.report.out_of_range, 0);
        assert!(!dir.path().join("events.csv.partial").exists());
    }

    #[test]
    fn the_sensor_size_is_kept_in_a_comment_the_reader_honours() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("events.csv");
        let mut events = EventBuffer::new();
        events.push(5, 639, 479, 1);
        events.push(9, 0, 3, 0);
        let g = Geometry::new(640, 480);
        let mut w: Box<dyn EventWriter> = Box::new(CsvWriter::create(&path, Some(g)).unwrap());
        w.write(&events).unwrap();
        w.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, "t,x,y,p\n# geometry: 640x480\n5,639,479,1\n9,0,3,0\n");
        let rec = io::read_all(&path, &ReadOptions::default()).unwrap();
        assert_eq!(rec.metadata.geometry, Some(g));
        assert_eq!(rec.events, events);
        assert!(rec.report.warnings.is_empty(), "{:?}", rec.report);
    }

    #[test]
    fn empty_stream_has_only_the_header() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("empty.csv");
        let w: Box<dyn EventWriter> = Box::new(CsvWriter::create(&path, None).unwrap());
        w.finish().unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "t,x,y,p\n");
        let rec = io::read_all(&path, &ReadOptions::default()).unwrap();
        assert!(rec.events.is_empty());
    }

    #[test]
    fn unfinished_writer_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("gone.csv");
        {
            let mut w = CsvWriter::create(&path, None).unwrap();
            w.write(&edge_events()).unwrap();
        }
        assert!(!path.exists());
        assert!(!dir.path().join("gone.csv.partial").exists());
    }
}
