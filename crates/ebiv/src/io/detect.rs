//! Format detection by content; the file extension only breaks ties (formats.md §18.1).

use super::prophesee_header::{read_up_to, PropheseeHeader};
use super::ReadSeek;
use crate::error::{Error, Result};
use std::io::SeekFrom;
use std::path::Path;

/// Event file formats ebiv reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Format {
    /// Prophesee RAW whose encoding is resolved from its header when opened.
    Raw,
    /// Prophesee RAW, EVT 2.0.
    Evt2,
    /// Prophesee RAW, EVT 2.1.
    Evt21,
    /// Prophesee RAW, EVT 3.0.
    Evt3,
    /// Prophesee DAT (CD / Event2d records).
    Dat,
    /// iniVation AEDAT 4.0.
    Aedat4,
    /// iniVation AEDAT 2.0 (and header-less 1.0 is not accepted).
    Aedat2,
    /// iniVation AEDAT 3.1.
    Aedat31,
    /// Event Stream (`.es`), DVS type.
    EventStream,
    /// Text / CSV, one event per line.
    Text,
    /// NumPy `.npy` structured array.
    Npy,
    /// NumPy `.npz` archive of column arrays.
    Npz,
    /// The EBIV authors' `.evt` format (64-byte header, 8-byte records).
    EbivEvt,
    /// HDF5: Metavision's `/CD/events` (ECF-compressed or plain) or event columns
    /// (`events/x`, `events/y`, `events/t`, `events/p`).
    Hdf5,
    /// Events handed over in memory ([`super::open_events`]), not read from a file.
    Memory,
}

impl Format {
    /// A short human-readable name.
    pub fn name(self) -> &'static str {
        match self {
            Format::Raw => "Prophesee RAW",
            Format::Evt2 => "Prophesee RAW EVT 2.0",
            Format::Evt21 => "Prophesee RAW EVT 2.1",
            Format::Evt3 => "Prophesee RAW EVT 3.0",
            Format::Dat => "Prophesee DAT",
            Format::Aedat4 => "iniVation AEDAT 4.0",
            Format::Aedat2 => "iniVation AEDAT 2.0",
            Format::Aedat31 => "iniVation AEDAT 3.1",
            Format::EventStream => "Event Stream (.es)",
            Format::Text => "text/CSV",
            Format::Npy => "NumPy .npy",
            Format::Npz => "NumPy .npz",
            Format::EbivEvt => "EBIV .evt",
            Format::Hdf5 => "HDF5",
            Format::Memory => "events in memory",
        }
    }

    /// Parse a user's format name (`evt3`, `dat`, `aedat4`, `csv`, `npz`, …).
    pub fn parse(name: &str) -> Option<Format> {
        let n = name.to_ascii_lowercase();
        Some(match n.as_str() {
            "raw" => Format::Raw,
            "evt2" | "evt2.0" => Format::Evt2,
            "evt21" | "evt2.1" => Format::Evt21,
            "evt3" | "evt3.0" => Format::Evt3,
            "dat" => Format::Dat,
            "aedat4" => Format::Aedat4,
            "aedat2" | "aedat" => Format::Aedat2,
            "aedat3" | "aedat31" | "aedat3.1" => Format::Aedat31,
            "es" => Format::EventStream,
            "csv" | "txt" | "text" => Format::Text,
            "npy" => Format::Npy,
            "npz" => Format::Npz,
            "evt" | "ebiv" => Format::EbivEvt,
            "hdf5" | "h5" => Format::Hdf5,
            _ => return None,
        })
    }
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// How many leading bytes detection looks at.
const SNIFF_BYTES: usize = 4096;

/// Detect the format of the file at `path` (RAW resolved to its encoding when the header
/// says it).
pub fn detect_format(path: impl AsRef<Path>) -> Result<Format> {
    let path = path.as_ref();
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let context = path.display().to_string();
    let format = detect_source(&mut file, &context, ext.as_deref())?;
    if format == Format::Raw {
        file.seek(SeekFrom::Start(0))
            .map_err(|e| Error::io(path, e))?;
        let header = PropheseeHeader::read(&mut file, &context)?;
        if let Some(enc) = header.encoding(&context)? {
            return Ok(enc.format());
        }
    }
    Ok(format)
}

use std::io::Seek;

/// Detect the format of `source` from its first bytes and rewind it.
pub(crate) fn detect_source(
    source: &mut dyn ReadSeek,
    context: &str,
    extension: Option<&str>,
) -> Result<Format> {
    let mut head = vec![0u8; SNIFF_BYTES];
    let n = read_up_to(source, &mut head)?;
    head.truncate(n);
    source.seek(SeekFrom::Start(0))?;
    classify(&head, extension).ok_or_else(|| Error::UnknownFormat {
        path: context.into(),
        hint: describe_unknown(&head, extension),
    })
}

fn classify(head: &[u8], extension: Option<&str>) -> Option<Format> {
    if head.starts_with(b"#!AER-DAT4.0") {
        return Some(Format::Aedat4);
    }
    if head.starts_with(b"#!AER-DAT3.1") {
        return Some(Format::Aedat31);
    }
    if head.starts_with(b"#!AER-DAT2.0") {
        return Some(Format::Aedat2);
    }
    if head.starts_with(b"Event Stream") {
        return Some(Format::EventStream);
    }
    if head.starts_with(b"\x93NUMPY") {
        return Some(Format::Npy);
    }
    if head.starts_with(b"PK\x03\x04") || head.starts_with(b"PK\x05\x06") {
        return Some(Format::Npz);
    }
    if looks_like_hdf5(head) {
        return Some(Format::Hdf5);
    }
    if looks_like_ebiv_evt(head) {
        return Some(Format::EbivEvt);
    }
    if head.starts_with(b"% ") {
        let header_text = String::from_utf8_lossy(head);
        let is_dat = header_text.contains("% Data file containing") || extension == Some("dat");
        return Some(if is_dat { Format::Dat } else { Format::Raw });
    }
    if !head.is_empty() && looks_like_text(head) {
        return Some(Format::Text);
    }
    match extension? {
        "raw" => Some(Format::Raw),
        "dat" => Some(Format::Dat),
        "csv" | "txt" => Some(Format::Text),
        _ => None,
    }
}

/// The HDF5 signature, at the start of the file or after a user block of 512, 1024 or 2048
/// bytes (HDF5 File Format Specification, §II.A: the superblock sits at 0 or a power of two
/// from 512 on).
fn looks_like_hdf5(head: &[u8]) -> bool {
    const SIGNATURE: &[u8] = b"\x89HDF\r\n\x1a\n";
    [0usize, 512, 1024, 2048]
        .iter()
        .any(|&at| head.get(at..at + SIGNATURE.len()) == Some(SIGNATURE))
}

/// The EBIV `.evt` header: signature `EVT3`/`EVT2`, then a header length of 48..=4096 at
/// byte 36 (formats.md §13).
fn looks_like_ebiv_evt(head: &[u8]) -> bool {
    if head.len() < 48 || !(head.starts_with(b"EVT3") || head.starts_with(b"EVT2")) {
        return false;
    }
    let header_len = u32::from_le_bytes([head[36], head[37], head[38], head[39]]);
    (48..=4096).contains(&header_len)
}

/// Printable ASCII with digits and separators only (a text event list).
fn looks_like_text(head: &[u8]) -> bool {
    // A chunk boundary may cut a multi-byte character; only ASCII matters here.
    let printable = head
        .iter()
        .all(|&b| b.is_ascii_graphic() || b == b' ' || b == b'\t' || b == b'\n' || b == b'\r');
    printable && head.iter().any(|b| b.is_ascii_digit())
}

fn describe_unknown(head: &[u8], extension: Option<&str>) -> String {
    if head.is_empty() {
        return "the file is empty".into();
    }
    let shown: String = head
        .iter()
        .take(16)
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ");
    format!(
        "first bytes {shown}, extension {}; ebiv reads Prophesee RAW (EVT 2/2.1/3) and DAT, AEDAT 2/3.1/4, Event Stream, text/CSV, .npy/.npz and EBIV .evt; pass --format to force one",
        extension.unwrap_or("none")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn content_beats_extension() {
        assert_eq!(
            classify(b"#!AER-DAT4.0\r\n", Some("raw")),
            Some(Format::Aedat4)
        );
        assert_eq!(classify(b"% evt 3.0\n", Some("dat")), Some(Format::Dat));
        assert_eq!(classify(b"% evt 3.0\n", Some("bin")), Some(Format::Raw));
        assert_eq!(
            classify(b"% Data file containing Event2d events\n", None),
            Some(Format::Dat)
        );
        assert_eq!(classify(b"t,x,y,p\n1,2,3,1\n", None), Some(Format::Text));
        assert_eq!(
            classify(&[0xff, 0x00, 0x13], Some("raw")),
            Some(Format::Raw)
        );
        assert_eq!(classify(&[0xff, 0x00, 0x13], Some("xyz")), None);
    }

    #[test]
    fn hdf5_is_found_at_the_start_or_after_a_user_block() {
        let signature = b"\x89HDF\r\n\x1a\n";
        assert_eq!(classify(signature, Some("xyz")), Some(Format::Hdf5));
        let mut blocked = vec![0u8; 512];
        blocked.extend_from_slice(signature);
        assert_eq!(classify(&blocked, None), Some(Format::Hdf5));
        let mut elsewhere = vec![0u8; 100];
        elsewhere.extend_from_slice(signature);
        assert_ne!(classify(&elsewhere, None), Some(Format::Hdf5));
    }
}
