//! Prophesee RAW files: the `% ` header, then an EVT 2.0, 2.1 or 3.0 body.

use super::bytestream::WordStreamReader;
use super::evt2::Evt2Decoder;
use super::evt21::Evt21Decoder;
use super::evt3::Evt3Decoder;
use super::prophesee_header::{PropheseeHeader, RawEncoding};
use super::{FormatReader, Metadata, ReadOptions, ReadSeek};
use crate::error::{Error, Result};
use std::io::{Seek, SeekFrom};

/// Why a file without a `% ` header is not read as RAW: it is empty, it is text, or it is
/// binary without a header (then an EVT stream can still be read with an explicit encoding).
fn not_raw(source: &mut Box<dyn ReadSeek>, context: &str) -> Result<Error> {
    use std::io::Read;
    source.seek(SeekFrom::Start(0))?;
    let mut start = Vec::with_capacity(256);
    source.take(256).read_to_end(&mut start)?;
    let message = if start.is_empty() {
        "the file is empty".to_string()
    } else if start
        .iter()
        .all(|&b| b.is_ascii_graphic() || b.is_ascii_whitespace())
    {
        let line = String::from_utf8_lossy(&start);
        let line = line.lines().next().unwrap_or_default();
        format!(
            "this is a text file, not a Prophesee RAW recording (which starts with `% ` header lines); it begins `{}`",
            line.chars().take(60).collect::<String>()
        )
    } else {
        "no `% ` header, as Prophesee RAW files have; if this is a headerless EVT stream, pass --raw-encoding evt2|evt21|evt3".to_string()
    };
    Ok(Error::unsupported(context, message))
}

/// Open a RAW file. `forced` overrides the header's encoding; `options.raw_encoding` is the
/// fallback when the header does not state one.
pub(crate) fn open(
    mut source: Box<dyn ReadSeek>,
    context: String,
    forced: Option<RawEncoding>,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    let header = PropheseeHeader::read(&mut source, &context)?;
    if header.length == 0 && forced.is_none() && options.raw_encoding.is_none() {
        return Err(not_raw(&mut source, &context)?);
    }
    source.seek(SeekFrom::Start(header.length))?;
    let encoding = match forced {
        Some(e) => e,
        None => header.encoding(&context)?.or(options.raw_encoding).ok_or_else(|| {
            Error::unsupported(
                &context,
                "the RAW header does not name its encoding (no `format`, `evt` or known `system_ID`); pass --raw-encoding evt2|evt21|evt3",
            )
        })?,
    };
    let metadata = metadata_from_header(&header, encoding.format(), options);
    if metadata.geometry.is_none() {
        return Err(Error::unsupported(
            &context,
            "the RAW header does not give the sensor size (no `format` size, `geometry` or known `system_ID`); pass --geometry WIDTHxHEIGHT",
        ));
    }
    let offset_us = time_origin(&header, &context)?;
    let geometry = metadata.geometry;
    let body = header.length;
    let batch = options.batch_bytes;
    Ok(match encoding {
        RawEncoding::Evt2 => Box::new(WordStreamReader::new(
            source,
            Evt2Decoder::new(geometry, offset_us),
            metadata,
            context,
            body,
            batch,
        )),
        RawEncoding::Evt21 => Box::new(WordStreamReader::new(
            source,
            Evt21Decoder::new(geometry, header.evt21_order(), offset_us),
            metadata,
            context,
            body,
            batch,
        )),
        RawEncoding::Evt3 => Box::new(WordStreamReader::new(
            source,
            Evt3Decoder::new(geometry, offset_us),
            metadata,
            context,
            body,
            batch,
        )),
    })
}

/// Metadata from a Prophesee header: geometry by OpenEB precedence, else the user's.
pub(crate) fn metadata_from_header(
    header: &PropheseeHeader,
    format: super::Format,
    options: &ReadOptions,
) -> Metadata {
    let mut metadata = Metadata::new(format);
    metadata.header = header.entries.clone();
    metadata.geometry = header.geometry(&mut metadata.notes).or(options.geometry);
    metadata.sensor = [
        "sensor_name",
        "plugin_name",
        "generation",
        "sensor_generation",
    ]
    .iter()
    .find_map(|k| header.get(k))
    .map(str::to_string);
    metadata.serial = header.get("serial_number").map(str::to_string);
    metadata
}

/// The `% t0 <µs>` key (written by faery and by ebiv's EVT 3.0 writer) moves the decoded
/// sensor clock to absolute time.
fn time_origin(header: &PropheseeHeader, context: &str) -> Result<i64> {
    match header.get("t0") {
        None => Ok(0),
        Some(v) => v.trim().parse::<i64>().map_err(|_| {
            Error::corrupt(
                context,
                0,
                format!("header key `t0` is not an integer (`{v}`)"),
            )
        }),
    }
}
