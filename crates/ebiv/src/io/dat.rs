//! Prophesee DAT files: `% ` header, one byte event type, one byte event size, then 8-byte
//! records `u32 t, u32 data` (formats.md §5; OpenEB `dat_event_file_reader.cpp`).

use super::bytestream::{WordDecoder, WordStreamReader};
use super::prophesee_header::{read_up_to, PropheseeHeader};
use super::time32::Unwrap32;
use super::{DecodeReport, Format, FormatReader, ReadOptions, ReadSeek};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry, Trigger};
use std::io::{Seek, SeekFrom};

const TYPE_EVENT2D: u8 = 0x00;
const TYPE_EVENT_CD: u8 = 0x0C;
const TYPE_EXT_TRIGGER: u8 = 0x0E;

/// Bit layout of CD records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Layout {
    /// Version 2: x bits 0–13, y bits 14–27, p bits 28–31.
    V2,
    /// Version 1 (old ATIS): x 9 bits, y 8 bits, p 1 bit.
    V1,
    /// Trigger records: value bits 0–3, channel bits 26–31.
    Trigger,
}

pub(crate) fn open(
    mut source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    let header = PropheseeHeader::read(&mut source, &context)?;
    source.seek(SeekFrom::Start(header.length))?;
    let mut type_size = [0u8; 2];
    if read_up_to(&mut source, &mut type_size)? < 2 {
        return Err(Error::corrupt(
            &context,
            header.length,
            "DAT file ends before its event type and size bytes",
        ));
    }
    let [event_type, event_size] = type_size;
    if event_size != 8 {
        return Err(Error::corrupt(
            &context,
            header.length + 1,
            format!("DAT event size is {event_size} bytes; only 8-byte records exist"),
        ));
    }
    let mut metadata = super::raw::metadata_from_header(&header, Format::Dat, options);
    let version = header.get("Version").map(str::trim);
    let layout = match (event_type, version) {
        (TYPE_EXT_TRIGGER, _) => Layout::Trigger,
        (TYPE_EVENT2D | TYPE_EVENT_CD, Some("1")) => Layout::V1,
        (TYPE_EVENT2D | TYPE_EVENT_CD, None) => {
            metadata
                .notes
                .push("DAT header has no `Version`; decoded as version 1 (old ATIS layout)".into());
            Layout::V1
        }
        (TYPE_EVENT2D | TYPE_EVENT_CD, Some(_)) => Layout::V2,
        (other, _) => {
            return Err(Error::unsupported(
                &context,
                format!("DAT event type {other:#04x} is not events or triggers (0x00, 0x0C, 0x0E)"),
            ))
        }
    };
    metadata.notes.push(
        "DAT time is usually already shifted by the writer (Metavision); it cannot be told from the file".into(),
    );
    let decoder = DatDecoder {
        layout,
        geometry: metadata.geometry,
        clock: Unwrap32::default(),
    };
    Ok(Box::new(WordStreamReader::new(
        source,
        decoder,
        metadata,
        context,
        header.length + 2,
        options.batch_bytes,
    )))
}

struct DatDecoder {
    layout: Layout,
    geometry: Option<Geometry>,
    /// The 32-bit clock, unwrapped.
    clock: Unwrap32,
}

impl WordDecoder for DatDecoder {
    const WORD_BYTES: usize = 8;

    fn decode(
        &mut self,
        bytes: &[u8],
        _offset: u64,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        out.reserve(bytes.len() / 8);
        let (width, height) = self
            .geometry
            .map_or((u32::MAX, u32::MAX), |g| (g.width, g.height));
        for rec in bytes.chunks_exact(8) {
            let raw_t = u32::from_le_bytes([rec[0], rec[1], rec[2], rec[3]]);
            let data = u32::from_le_bytes([rec[4], rec[5], rec[6], rec[7]]);
            let t = self.clock.unwrap(raw_t);
            let (x, y, p) = match self.layout {
                Layout::V2 => (data & 0x3FFF, (data >> 14) & 0x3FFF, (data >> 28) & 0xF),
                Layout::V1 => (data & 0x1FF, (data >> 9) & 0xFF, (data >> 17) & 1),
                Layout::Trigger => {
                    out.triggers.push(Trigger {
                        t,
                        channel: (data >> 26) as u8,
                        value: (data & 0xF) as u8,
                    });
                    continue;
                }
            };
            if x >= width || y >= height {
                report.out_of_range += 1;
                continue;
            }
            out.push(t, x as u16, y as u16, (p != 0) as u8);
        }
    }
}
