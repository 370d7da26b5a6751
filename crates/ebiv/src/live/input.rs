//! Byte sources of live runs: a recording that is still being written, followed as it grows
//! (the way the Metavision recorder appends to a RAW file), and a pipe such as standard input.
//! Both plug into the ordinary readers ([`crate::io::open_source`]), which carry a word split
//! across two reads over to the next, so a half-written word is completed by the next read,
//! never taken for the end of the recording.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// How often a followed file is polled for new data.
const POLL: Duration = Duration::from_millis(2);

/// Asked between reads whether the run is to stop (Ctrl-C, a caller's request).
pub type StopCheck = std::sync::Arc<dyn Fn() -> bool + Send + Sync>;

/// A file that another process is still writing: at its end a read waits for more data,
/// and reports the end only once the file has not grown for `idle`, or when `stop` says so.
pub struct GrowingFile {
    file: File,
    path: PathBuf,
    idle: Duration,
    stop: StopCheck,
    /// When data last arrived (or the file was opened).
    last_growth: Instant,
}

impl GrowingFile {
    /// Open `path` (it must exist) to follow it.
    pub fn open(path: &Path, idle: Duration, stop: StopCheck) -> crate::Result<Self> {
        let file = File::open(path).map_err(|e| crate::Error::io(path, e))?;
        Ok(GrowingFile {
            file,
            path: path.to_path_buf(),
            idle,
            stop,
            last_growth: Instant::now(),
        })
    }

    /// The followed file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Read for GrowingFile {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        loop {
            let n = self.file.read(buf)?;
            if n > 0 {
                self.last_growth = Instant::now();
                return Ok(n);
            }
            if (self.stop)() || self.last_growth.elapsed() >= self.idle {
                return Ok(0);
            }
            std::thread::sleep(POLL);
        }
    }
}

impl Seek for GrowingFile {
    /// Seeks from the start or the current position; the end of a growing file is not
    /// known, so a seek from the end is refused (formats that need it cannot be followed).
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        match pos {
            SeekFrom::End(_) => Err(not_seekable("a file being followed")),
            other => self.file.seek(other),
        }
    }
}

fn not_seekable(what: &str) -> io::Error {
    io::Error::new(
        io::ErrorKind::Unsupported,
        format!("{what} has no known end: this format needs the whole file (live input takes RAW EVT 2.0/2.1/3.0, DAT, ES, AEDAT 2 and text)"),
    )
}

/// Most bytes a [`PipeInput`] keeps for seeking back into the start of the stream (the
/// header and format detection).
pub const PIPE_REWIND_BYTES: usize = 1 << 20;

/// A stream that cannot seek (a pipe, standard input), made seekable within its first
/// [`PIPE_REWIND_BYTES`]: the readers rewind once after sniffing the format and seek to the
/// end of the header, and read straight on from there. The stream is read on a thread of its
/// own, so that a stop request ends a wait for data that may never come.
pub struct PipeInput {
    chunks: Receiver<io::Result<Vec<u8>>>,
    /// The chunk being handed out, and how much of it has been.
    chunk: Vec<u8>,
    used: usize,
    /// The first bytes of the stream, while the position stays within them.
    head: Vec<u8>,
    /// Whether `head` still holds every byte read so far.
    head_complete: bool,
    /// Position in the stream.
    position: u64,
    /// Bytes taken from the stream.
    taken: u64,
    stop: StopCheck,
}

/// Bytes the thread reading a pipe reads at once.
const PIPE_CHUNK: usize = 1 << 16;

impl PipeInput {
    /// Read `inner` on a thread of its own; `stop` ends the stream early (a read then
    /// reports its end).
    pub fn new<R: Read + Send + 'static>(mut inner: R, stop: StopCheck) -> Self {
        let (send, chunks) = sync_channel::<io::Result<Vec<u8>>>(8);
        // The thread ends at the end of the stream, or when the input is dropped (its next
        // send fails); a pipe that never ends keeps it waiting in `read`, harmlessly.
        let _ = std::thread::Builder::new()
            .name("ebiv-pipe".into())
            .spawn(move || loop {
                let mut chunk = vec![0u8; PIPE_CHUNK];
                let result = match inner.read(&mut chunk) {
                    Ok(0) => return,
                    Ok(n) => {
                        chunk.truncate(n);
                        Ok(chunk)
                    }
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(e) => Err(e),
                };
                let failed = result.is_err();
                if send.send(result).is_err() || failed {
                    return;
                }
            });
        PipeInput {
            chunks,
            chunk: Vec::new(),
            used: 0,
            head: Vec::new(),
            head_complete: true,
            position: 0,
            taken: 0,
            stop,
        }
    }

    /// Bytes from the stream into `buf`: waits for a chunk, checking for a stop request.
    fn take(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        while self.used == self.chunk.len() {
            if (self.stop)() {
                return Ok(0);
            }
            match self.chunks.recv_timeout(POLL_PIPE) {
                Ok(chunk) => {
                    self.chunk = chunk?;
                    self.used = 0;
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return Ok(0),
            }
        }
        let n = buf.len().min(self.chunk.len() - self.used);
        buf[..n].copy_from_slice(&self.chunk[self.used..self.used + n]);
        self.used += n;
        Ok(n)
    }
}

/// How often a wait for a pipe's data looks for a stop request.
const POLL_PIPE: Duration = Duration::from_millis(20);

impl Read for PipeInput {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.position < self.taken {
            // Re-reading kept bytes after a seek back.
            let start = self.position as usize;
            let n = buf.len().min(self.head.len() - start);
            buf[..n].copy_from_slice(&self.head[start..start + n]);
            self.position += n as u64;
            return Ok(n);
        }
        let n = self.take(buf)?;
        if self.head_complete {
            if self.head.len() + n <= PIPE_REWIND_BYTES {
                self.head.extend_from_slice(&buf[..n]);
            } else {
                self.head_complete = false;
                self.head = Vec::new();
            }
        }
        self.taken += n as u64;
        self.position += n as u64;
        Ok(n)
    }
}

impl Seek for PipeInput {
    /// Seeks back within the kept start of the stream, or forward by reading and
    /// discarding; anything else is an error.
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        let target = match pos {
            SeekFrom::Start(n) => n,
            SeekFrom::Current(d) => self.position.checked_add_signed(d).ok_or_else(|| {
                io::Error::new(io::ErrorKind::InvalidInput, "seek before the start")
            })?,
            SeekFrom::End(_) => return Err(not_seekable("a pipe")),
        };
        if target <= self.taken {
            if target < self.taken && !self.head_complete {
                return Err(io::Error::new(
                    io::ErrorKind::Unsupported,
                    format!(
                        "a pipe cannot go back more than {PIPE_REWIND_BYTES} bytes into its start"
                    ),
                ));
            }
            self.position = target;
            return Ok(target);
        }
        self.position = self.taken;
        let mut scratch = [0u8; 8192];
        while self.position < target {
            let want = scratch.len().min((target - self.position) as usize);
            if self.read(&mut scratch[..want])? == 0 {
                break;
            }
        }
        Ok(self.position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;
    use std::sync::Arc;

    fn never() -> StopCheck {
        Arc::new(|| false)
    }

    #[test]
    fn a_pipe_rewinds_within_its_start_and_reads_on() {
        let data: Vec<u8> = (0..=255u8).cycle().take(10_000).collect();
        let mut pipe = PipeInput::new(std::io::Cursor::new(data.clone()), never());
        let mut head = [0u8; 100];
        pipe.read_exact(&mut head).unwrap();
        assert_eq!(pipe.seek(SeekFrom::Start(0)).unwrap(), 0);
        let mut all = Vec::new();
        pipe.read_to_end(&mut all).unwrap();
        assert_eq!(all, data);
        assert!(pipe.seek(SeekFrom::End(0)).is_err());
        let mut pipe = PipeInput::new(std::io::Cursor::new(data.clone()), never());
        assert_eq!(pipe.seek(SeekFrom::Start(5000)).unwrap(), 5000);
        let mut rest = Vec::new();
        pipe.read_to_end(&mut rest).unwrap();
        assert_eq!(rest, data[5000..]);
        // A stop request ends a wait for data that does not come.
        let (_keep_open, silent) = std::os::unix::net::UnixStream::pair().unwrap();
        let begun = std::time::Instant::now();
        let stop: StopCheck = Arc::new(move || begun.elapsed() > Duration::from_millis(200));
        let mut waiting = PipeInput::new(silent, stop);
        let mut all = Vec::new();
        waiting.read_to_end(&mut all).unwrap();
        assert!(all.is_empty() && begun.elapsed() < Duration::from_secs(5));
    }

    #[test]
    fn a_growing_file_waits_for_data_and_ends_when_idle() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grow.bin");
        let mut writer = File::create(&path).unwrap();
        writer.write_all(b"abc").unwrap();
        let mut file = GrowingFile::open(&path, Duration::from_millis(300), never()).unwrap();
        let appender = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            writer.write_all(b"def").unwrap();
        });
        let mut all = Vec::new();
        file.read_to_end(&mut all).unwrap();
        appender.join().unwrap();
        assert_eq!(all, b"abcdef");
        assert!(file.seek(SeekFrom::End(0)).is_err());
        // A stop request ends the wait at once.
        let mut stopped =
            GrowingFile::open(&path, Duration::from_secs(60), Arc::new(|| true)).unwrap();
        let mut all = Vec::new();
        stopped.read_to_end(&mut all).unwrap();
        assert_eq!(all, b"abcdef");
    }
}
