//! A reader for formats that are a plain sequence of fixed-size words after a header: the
//! file is read in chunks, whole words are handed to a stateful decoder, and a word split
//! across two chunks is carried over.

use super::{DecodeReport, FormatReader, Metadata, ReadSeek, ResumePoint};
use crate::error::{Error, Result};
use crate::event::EventBuffer;
use std::io::{Read, SeekFrom};

/// A stateful decoder of fixed-size words; state (time base, vector base, continuation
/// words) persists across calls.
pub(crate) trait WordDecoder: Send {
    /// Size of one word in bytes.
    const WORD_BYTES: usize;
    /// Decode `bytes` (a whole number of words starting at file offset `offset`) into `out`.
    fn decode(
        &mut self,
        bytes: &[u8],
        offset: u64,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    );
    /// The Metavision SDK time shift, once the first time base has been seen.
    fn metavision_time_shift(&self) -> Option<i64> {
        None
    }
    /// Called once at the end of the stream.
    fn finish(&mut self, _end_offset: u64, _report: &mut DecodeReport) {}
    /// What the decoder carries from one word to the next (time base, vector base, …), to
    /// resume decoding at a word boundary later ([`super::index`]); `None` for decoders that
    /// do not support resuming.
    fn state(&self) -> Option<Vec<i64>> {
        None
    }
    /// Resume with a state [`WordDecoder::state`] gave for the same file; `None` when the
    /// state is not one of this decoder's.
    fn restore(&mut self, _state: &[i64]) -> Option<()> {
        None
    }
}

/// [`FormatReader`] over a [`WordDecoder`].
pub(crate) struct WordStreamReader<D: WordDecoder> {
    source: Box<dyn ReadSeek>,
    decoder: D,
    metadata: Metadata,
    report: DecodeReport,
    context: String,
    buf: Vec<u8>,
    /// Bytes of an incomplete word carried over from the previous chunk.
    carry: usize,
    /// File offset of `buf[0]`.
    offset: u64,
    /// File offset of the first word, after the header.
    body_offset: u64,
    done: bool,
}

impl<D: WordDecoder> WordStreamReader<D> {
    /// A reader whose body starts at file offset `body_offset`, the current position of `source`.
    pub fn new(
        source: Box<dyn ReadSeek>,
        decoder: D,
        metadata: Metadata,
        context: String,
        body_offset: u64,
        batch_bytes: usize,
    ) -> Self {
        let chunk = (batch_bytes.max(4096) / D::WORD_BYTES) * D::WORD_BYTES;
        WordStreamReader {
            source,
            decoder,
            metadata,
            report: DecodeReport::default(),
            context,
            buf: vec![0; chunk],
            carry: 0,
            offset: body_offset,
            body_offset,
            done: false,
        }
    }

    /// Fill the buffer after the carried bytes; returns how many bytes are now in it. A short
    /// read that completes a word ends the filling: a pipe or a file being written hands over
    /// what it has, and the words already there are decoded without waiting for more.
    fn fill(&mut self) -> Result<usize> {
        let mut filled = self.carry;
        while filled < self.buf.len() {
            let wanted = self.buf.len() - filled;
            match self.source.read(&mut self.buf[filled..]) {
                Ok(0) => break,
                Ok(n) => {
                    filled += n;
                    if n < wanted && filled >= D::WORD_BYTES {
                        break;
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
        }
        Ok(filled)
    }
}

impl<D: WordDecoder> FormatReader for WordStreamReader<D> {
    fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        if self.done {
            return Ok(false);
        }
        let filled = self.fill()?;
        let whole = filled / D::WORD_BYTES * D::WORD_BYTES;
        if whole == 0 {
            self.done = true;
            if filled > 0 {
                self.report.truncated_bytes += filled as u64;
                self.report.warn(format!(
                    "{}: file ends inside a {}-byte word at byte {}; {} trailing bytes ignored",
                    self.context,
                    D::WORD_BYTES,
                    self.offset,
                    filled
                ));
            }
            self.decoder
                .finish(self.offset + filled as u64, &mut self.report);
            return Ok(false);
        }
        self.decoder
            .decode(&self.buf[..whole], self.offset, out, &mut self.report);
        self.buf.copy_within(whole..filled, 0);
        self.carry = filled - whole;
        self.offset += whole as u64;
        Ok(true)
    }

    fn report(&self) -> &DecodeReport {
        &self.report
    }

    fn metavision_time_shift(&self) -> Option<i64> {
        self.decoder.metavision_time_shift()
    }

    fn position(&self) -> Option<u64> {
        Some(self.offset)
    }

    fn resume_point(&self) -> Option<ResumePoint> {
        Some(ResumePoint {
            offset: self.offset,
            state: self.decoder.state()?,
        })
    }

    /// Resumes only at a word boundary of the file's body, with a state whose numbers stay far
    /// from overflowing (a damaged index file is an error, never a panic or a wrapped time).
    fn resume(&mut self, point: &ResumePoint) -> Result<()> {
        let mismatch = || {
            Error::corrupt(
                &self.context,
                point.offset,
                "the recording's index does not match the file (rebuild it with `ebiv index --force`)",
            )
        };
        let size = self.source.seek(SeekFrom::End(0))?;
        let aligned = point
            .offset
            .checked_sub(self.body_offset)
            .is_some_and(|o| o % D::WORD_BYTES as u64 == 0);
        let plausible = point.state.iter().all(|v| v.unsigned_abs() < 1 << 60);
        if !aligned || point.offset > size || !plausible {
            self.source
                .seek(SeekFrom::Start(self.offset + self.carry as u64))?;
            return Err(mismatch());
        }
        let saved = self.decoder.state();
        if self.decoder.restore(&point.state).is_none() {
            if let Some(saved) = saved {
                self.decoder.restore(&saved);
            }
            self.source
                .seek(SeekFrom::Start(self.offset + self.carry as u64))?;
            return Err(mismatch());
        }
        self.source.seek(SeekFrom::Start(point.offset))?;
        self.offset = point.offset;
        self.carry = 0;
        self.done = false;
        Ok(())
    }
}
