//! The streaming text reader: a look at the first lines decides columns, delimiter, time
//! unit and geometry (formats.md §11), then the file is parsed line by line in batches.

use super::parse::{find_byte, parse_i64, Delim, Fields, Line, LineParser};
use super::{check_columns, describe_columns, TextColumn, TimeUnit};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use crate::io::npy::TimeConv;
use crate::io::prophesee_header::read_up_to;
use crate::io::{DecodeReport, Format, FormatReader, Metadata, ReadOptions, ReadSeek};
use std::io::{Seek, SeekFrom};

/// How much of the file's start is examined for comments and a header.
const PREAMBLE_BYTES: usize = 1 << 20;
/// Smallest read buffer; also the longest line that is parsed rather than skipped.
const MIN_BUFFER: usize = 1 << 16;
/// Malformed lines named individually in the warning.
const NAMED_BAD_LINES: usize = 5;
/// Comment lines copied into the metadata.
const MAX_COMMENTS: usize = 32;
/// Malformed lines beyond this many abort reading once they exceed 1 % of the lines so far.
const EARLY_ABORT: u64 = 1000;

/// What the first lines of a file tell.
#[derive(Debug, Default)]
struct Preamble {
    /// 1-based line number and text of a column header line.
    header: Option<(u64, Vec<u8>)>,
    /// Column names from a comment such as `# t x y p`.
    comment_columns: Option<Vec<String>>,
    geometry: Option<Geometry>,
    /// A Metavision `%geometry:` line was seen.
    metavision: bool,
    /// 1-based line number and text of the first data line.
    first_data: Option<(u64, Vec<u8>)>,
    comments: Vec<String>,
}

fn strip_line(line: &[u8]) -> &[u8] {
    let line = line.strip_suffix(b"\r").unwrap_or(line);
    line.trim_ascii()
}

fn starts_numeric(line: &[u8]) -> bool {
    matches!(line.first(), Some(b'0'..=b'9' | b'-' | b'+' | b'.'))
}

/// `W,H`, `WxH` or `W H`.
fn parse_geometry(s: &str) -> Option<Geometry> {
    let mut parts = s
        .split(|c: char| c == ',' || c == 'x' || c == 'X' || c == ';' || c.is_whitespace())
        .filter(|p| !p.is_empty());
    let w = parts.next()?.parse::<u32>().ok()?;
    let h = parts.next()?.parse::<u32>().ok()?;
    (w > 0 && h > 0 && parts.next().is_none()).then_some(Geometry::new(w, h))
}

fn split_names(line: &str) -> Vec<String> {
    line.split(|c: char| c == ',' || c == ';' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(str::to_string)
        .collect()
}

fn scan_preamble(bytes: &[u8], complete: bool) -> Preamble {
    let mut pre = Preamble::default();
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut lines = bytes.split(|&b| b == b'\n').peekable();
    let mut line_no = 0u64;
    while let Some(raw) = lines.next() {
        // The last piece of an incomplete read may be a cut line.
        if lines.peek().is_none() && !complete {
            break;
        }
        line_no += 1;
        let line = strip_line(raw);
        if line.is_empty() {
            continue;
        }
        if let [b'#' | b'%', ..] = line {
            let text = String::from_utf8_lossy(line).into_owned();
            let body = text.trim_start_matches(['#', '%']).trim();
            let lower = body.to_lowercase();
            if let Some(rest) = lower.strip_prefix("geometry") {
                let rest = rest.trim_start_matches([':', '=', ' ']);
                if let Some(g) = parse_geometry(rest) {
                    pre.geometry = Some(g);
                    pre.metavision |= line.starts_with(b"%") && lower.starts_with("geometry:");
                }
            } else {
                let names = split_names(body);
                let roles: Vec<TextColumn> =
                    names.iter().map(|n| TextColumn::from_name(n).0).collect();
                let all_known = roles.iter().all(|&r| r != TextColumn::Skip);
                if all_known && check_columns(&roles).is_ok() {
                    pre.comment_columns = Some(names);
                }
            }
            if pre.comments.len() < MAX_COMMENTS {
                pre.comments.push(text);
            }
            continue;
        }
        if starts_numeric(line) || pre.header.is_some() {
            pre.first_data = Some((line_no, line.to_vec()));
            break;
        }
        pre.header = Some((line_no, line.to_vec()));
    }
    pre
}

pub(crate) fn open(
    mut source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    let mut head = vec![0u8; PREAMBLE_BYTES];
    let n = read_up_to(&mut source, &mut head)?;
    head.truncate(n);
    let pre = scan_preamble(&head, n < PREAMBLE_BYTES);
    drop(head);
    source.seek(SeekFrom::Start(0))?;

    let text = &options.text;
    let mut metadata = Metadata::new(Format::Text);
    let mut notes = Vec::new();
    let bad_columns = |line: u64, message: String| Error::Parse {
        context: context.clone(),
        line,
        message,
    };

    // Delimiter: the user's, else from the header or first data line.
    let delim = match (text.delimiter, &pre.header, &pre.first_data) {
        (Some(d), _, _) => Delim::of_byte(d),
        (None, Some((_, raw)), _) | (None, None, Some((_, raw))) => Delim::detect(raw),
        (None, None, None) => Delim::Blank,
    };

    // Columns and a unit carried by the header's time name.
    let mut header_unit = None;
    let columns: Vec<TextColumn> = if let Some(columns) = &text.columns {
        check_columns(columns).map_err(|m| Error::parameter("columns", m))?;
        notes.push(format!("columns {} (given)", describe_columns(columns)));
        columns.clone()
    } else if let Some((line, raw)) = &pre.header {
        let names: Vec<String> = Fields::new(raw, delim)
            .map(|f| String::from_utf8_lossy(f).into_owned())
            .collect();
        let mut columns = Vec::with_capacity(names.len());
        for name in &names {
            let (mut c, unit) = TextColumn::from_name(name);
            if c != TextColumn::Skip && columns.contains(&c) {
                c = TextColumn::Skip;
            }
            if c == TextColumn::T {
                header_unit = unit;
            }
            columns.push(c);
        }
        check_columns(&columns).map_err(|_| {
            bad_columns(
                *line,
                format!(
                    "the header names the columns ({}); ebiv needs t (or ts, timestamp, time), x, y and p (or pol, polarity, on) — or give the column order explicitly",
                    names.join(", ")
                ),
            )
        })?;
        notes.push(format!(
            "columns {} from the header on line {line}",
            describe_columns(&columns)
        ));
        columns
    } else if let Some(names) = &pre.comment_columns {
        let columns: Vec<TextColumn> = names.iter().map(|n| TextColumn::from_name(n).0).collect();
        header_unit = names
            .iter()
            .map(|n| TextColumn::from_name(n))
            .find(|(c, _)| *c == TextColumn::T)
            .and_then(|(_, u)| u);
        notes.push(format!(
            "columns {} from a comment line",
            describe_columns(&columns)
        ));
        columns
    } else if pre.metavision {
        notes.push("columns x,y,p,t (Metavision CSV: `%geometry:` line, no header)".into());
        vec![TextColumn::X, TextColumn::Y, TextColumn::P, TextColumn::T]
    } else {
        notes.push("columns t,x,y,p (no header line)".into());
        vec![TextColumn::T, TextColumn::X, TextColumn::Y, TextColumn::P]
    };
    let comma_decimal = delim != Delim::Char(b',');

    // Time unit: the user's, else the header's, else from the first data line.
    let unit = match (text.time_unit, header_unit) {
        (TimeUnit::Auto, Some(u)) => {
            notes.push(format!("time unit {u:?} from the header"));
            u
        }
        (TimeUnit::Auto, None) => match &pre.first_data {
            Some((line, data)) if time_has_point(data, &columns, delim, comma_decimal) => {
                notes.push(format!(
                    "time in seconds (decimal point on line {line}); converted exactly, rounded to the nearest µs"
                ));
                TimeUnit::Seconds
            }
            _ => {
                notes.push("time in µs (integers)".into());
                TimeUnit::Microseconds
            }
        },
        (u, _) => {
            notes.push(format!("time unit {u:?} (given)"));
            u
        }
    };
    let time = match unit.micros_ratio() {
        Some((n, d)) => TimeConv::Ratio(n, d),
        None => TimeConv::Factor(unit.micros_per_unit()),
    };

    let geometry = pre.geometry.or(options.geometry);
    if let Some(g) = pre.geometry {
        metadata
            .header
            .push(("geometry".into(), format!("{},{}", g.width, g.height)));
    }
    for c in &pre.comments {
        metadata.header.push(("comment".into(), c.clone()));
    }
    notes.push(format!("fields separated by {}", delim.describe()));
    metadata.geometry = geometry;
    metadata.notes = notes;

    let last_needed = columns
        .iter()
        .rposition(|&c| c != TextColumn::Skip)
        .unwrap_or(0);
    let g = geometry.unwrap_or(Geometry::new(u32::MAX, u32::MAX));
    let parser = LineParser {
        roles: columns.get(..=last_needed).unwrap_or(&columns).to_vec(),
        delim,
        time,
        polarity: text.polarity,
        comma_decimal,
        width: g.width,
        height: g.height,
    };
    let capacity = options.batch_bytes.max(MIN_BUFFER);
    Ok(Box::new(TextReader {
        source,
        buf: vec![0; capacity],
        start: 0,
        end: 0,
        eof: false,
        done: false,
        skipping: false,
        consumed: 0,
        sink: LineSink {
            parser,
            header_line: pre.header.as_ref().map(|(l, _)| *l),
            line_no: 0,
            data_lines: 0,
            bad_lines: Vec::new(),
            report: DecodeReport::default(),
            context,
        },
        metadata,
    }))
}

/// Whether the time field of `data` has a decimal point (seconds).
fn time_has_point(data: &[u8], columns: &[TextColumn], delim: Delim, comma: bool) -> bool {
    let Some(i) = columns.iter().position(|&c| c == TextColumn::T) else {
        return false;
    };
    Fields::new(data, delim).nth(i).is_some_and(|f| {
        parse_i64(f).is_none()
            && f.iter()
                .any(|&b| b == b'.' || b == b'e' || b == b'E' || (comma && b == b','))
    })
}

/// Per-line state, apart from the read buffer.
struct LineSink {
    parser: LineParser,
    header_line: Option<u64>,
    /// Lines completed so far.
    line_no: u64,
    data_lines: u64,
    bad_lines: Vec<(u64, String)>,
    report: DecodeReport,
    context: String,
}

impl LineSink {
    #[inline]
    fn line(&mut self, line: &[u8], out: &mut EventBuffer) {
        self.line_no += 1;
        let line = match line {
            [rest @ .., b'\r'] => rest,
            l => l,
        };
        if !matches!(line.first(), Some(b'0'..=b'9')) {
            let line = if self.line_no == 1 {
                line.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(line)
            } else {
                line
            };
            match line.trim_ascii_start().first() {
                None | Some(b'#' | b'%') => return,
                _ if self.header_line == Some(self.line_no) => return,
                _ => {}
            }
        }
        self.data_lines += 1;
        match self.parser.parse(line) {
            Line::Event(t, x, y, p) => out.push(t, x, y, p),
            Line::OutOfRange => self.report.out_of_range += 1,
            Line::Malformed(why) => self.malformed(why.to_string()),
        }
    }

    fn malformed(&mut self, why: String) {
        self.report.malformed += 1;
        if self.bad_lines.len() < NAMED_BAD_LINES {
            self.bad_lines.push((self.line_no, why));
        }
    }

    fn too_many_malformed(&self) -> bool {
        self.report.malformed * 100 > self.data_lines
    }

    fn summary(&self) -> String {
        let named: Vec<String> = self
            .bad_lines
            .iter()
            .map(|(l, why)| format!("line {l}: {why}"))
            .collect();
        format!(
            "{} of {} data lines malformed ({}{}); columns read as {} separated by {}",
            self.report.malformed,
            self.data_lines,
            named.join("; "),
            if self.report.malformed as usize > named.len() {
                "; …"
            } else {
                ""
            },
            describe_columns(&self.parser.roles),
            self.parser.delim.describe()
        )
    }

    fn fail(&self) -> Error {
        Error::Parse {
            context: self.context.clone(),
            line: self.bad_lines.first().map_or(self.line_no, |(l, _)| *l),
            message: format!(
                "too many malformed lines (more than 1 %): {}; set the column order, delimiter or units if they are wrong",
                self.summary()
            ),
        }
    }
}

/// [`FormatReader`] for text files.
struct TextReader {
    source: Box<dyn ReadSeek>,
    buf: Vec<u8>,
    /// Unparsed bytes are `buf[start..end]`.
    start: usize,
    end: usize,
    eof: bool,
    done: bool,
    /// Inside a line longer than the buffer, which is being skipped.
    skipping: bool,
    /// Bytes of the file parsed so far.
    consumed: u64,
    sink: LineSink,
    metadata: Metadata,
}

impl TextReader {
    /// Move the unparsed bytes to the front and read until the buffer is full or the file ends.
    fn fill(&mut self) -> Result<()> {
        self.buf.copy_within(self.start..self.end, 0);
        self.end -= self.start;
        self.start = 0;
        if self.end < self.buf.len() && !self.eof {
            self.end += read_up_to(&mut self.source, &mut self.buf[self.end..])?;
            self.eof = self.end < self.buf.len();
        }
        Ok(())
    }

    fn finish(&mut self) -> Result<()> {
        self.done = true;
        let sink = &mut self.sink;
        if sink.report.malformed == 0 {
            return Ok(());
        }
        if sink.too_many_malformed() {
            return Err(sink.fail());
        }
        let summary = sink.summary();
        sink.report
            .warn(format!("{}: skipped {summary}", sink.context));
        Ok(())
    }
}

impl FormatReader for TextReader {
    fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        if self.done {
            return Ok(false);
        }
        self.fill()?;
        let chunk = &self.buf[..self.end];
        let mut pos = 0;
        if self.skipping {
            match find_byte(chunk, b'\n') {
                Some(i) => {
                    pos = i + 1;
                    self.skipping = false;
                }
                None => pos = self.end,
            }
        }
        // Complete lines end at the last newline; at the end of the file the rest is a line too.
        let limit = match chunk[pos..].iter().rposition(|&b| b == b'\n') {
            Some(i) => pos + i + 1,
            None if self.eof => self.end,
            None if pos == 0 && self.end > 0 => {
                // A line longer than the whole buffer: count it and skip to its end.
                self.sink.line_no += 1;
                self.sink.data_lines += 1;
                self.sink
                    .malformed(format!("line longer than {} bytes", self.buf.len()));
                self.skipping = true;
                pos = self.end;
                self.end
            }
            None => pos,
        };
        out.reserve((limit - pos) / 16);
        while pos < limit {
            let rest = &chunk[pos..limit];
            let len = find_byte(rest, b'\n').unwrap_or(rest.len());
            self.sink.line(&rest[..len], out);
            pos += len + 1;
        }
        let pos = pos.min(self.end);
        self.consumed += pos as u64;
        self.start = pos.min(self.end);
        if self.sink.report.malformed >= EARLY_ABORT && self.sink.too_many_malformed() {
            self.done = true;
            return Err(self.sink.fail());
        }
        if self.eof && self.start >= self.end {
            self.finish()?;
        }
        Ok(true)
    }

    fn report(&self) -> &DecodeReport {
        &self.sink.report
    }

    fn position(&self) -> Option<u64> {
        Some(self.consumed)
    }
}
