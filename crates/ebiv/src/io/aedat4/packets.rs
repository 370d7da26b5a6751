//! Decoding of AEDAT 4.0 packet bodies (formats.md §9): `EventPacket` (`EVTS`) and
//! `TriggerPacket` (`TRIG`) flatbuffers, after dv-processing's `events.fbs` and `trigger.fbs`.

use super::flatbuf::{self, FbError};
use crate::event::{EventBuffer, Trigger};
use crate::io::sink;
use crate::io::DecodeReport;

/// Size of one `dv::Event` struct: `i64 timestamp, i16 x, i16 y, bool polarity`, padded to 8.
const EVENT_BYTES: usize = 16;

/// `EventPacket` (identifier `EVTS`): field 0 is a vector of 16-byte `Event` structs.
pub(super) fn decode_events(
    body: &[u8],
    limits: (u32, u32),
    out: &mut EventBuffer,
    report: &mut DecodeReport,
) -> std::result::Result<(), FbError> {
    let root = flatbuf::root(body, b"EVTS")?;
    if let Some((_, elements)) = root.vector(0, EVENT_BYTES)? {
        push_events(elements, limits, out, report);
    }
    Ok(())
}

/// Append the events of a packed `Event` array, dropping (and counting) pixels outside
/// `limits` — negative coordinates included, as they read as large unsigned values.
fn push_events(
    elements: &[u8],
    (width, height): (u32, u32),
    out: &mut EventBuffer,
    report: &mut DecodeReport,
) {
    // `chunks_exact(16)` makes every index below a constant in bounds.
    #[inline(always)]
    fn x_of(c: &[u8]) -> u16 {
        u16::from_le_bytes([c[8], c[9]])
    }
    #[inline(always)]
    fn y_of(c: &[u8]) -> u16 {
        u16::from_le_bytes([c[10], c[11]])
    }
    #[inline(always)]
    fn t_of(c: &[u8]) -> i64 {
        i64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])
    }
    let mut records = elements.chunks_exact(EVENT_BYTES);
    let mut out_of_range = 0u64;
    let counted = &mut out_of_range;
    // One pass: each record is written into the next slot and kept when its pixel is on the
    // sensor.
    sink::append(out, records.len(), |sink| {
        sink.extend_while(&mut records, move |c| {
            let (x, y) = (x_of(c), y_of(c));
            let inside = ((x as u32) < width) & ((y as u32) < height);
            *counted += !inside as u64;
            Some((inside, t_of(c), x, y, (c[12] != 0) as u8))
        })
    });
    report.out_of_range += out_of_range;
}

/// `TriggerPacket` (identifier `TRIG`): field 0 is a vector of `Trigger` tables with fields
/// 0 `timestamp` (i64) and 1 `type` (i8). External-input edges (1 rising, 2 falling, 3 pulse)
/// become triggers on channel 0; other types (timestamp reset, generator, frame and exposure
/// markers) are counted as skipped.
pub(super) fn decode_triggers(
    body: &[u8],
    out: &mut EventBuffer,
    report: &mut DecodeReport,
) -> std::result::Result<(), FbError> {
    let root = flatbuf::root(body, b"TRIG")?;
    let Some(elements) = root.tables(0)? else {
        return Ok(());
    };
    let mark = out.triggers.len();
    let mut skipped = 0;
    for i in 0..elements.len() {
        let decoded = elements
            .get(i)
            .and_then(|t| Ok((t.i64(0, 0)?, t.i8(1, 0)?)));
        let (t, kind) = match decoded {
            Ok(v) => v,
            Err(e) => {
                out.triggers.truncate(mark);
                return Err(e);
            }
        };
        let value = match kind {
            1 | 3 => 1,
            2 => 0,
            _ => {
                skipped += 1;
                continue;
            }
        };
        out.triggers.push(Trigger {
            t,
            channel: 0,
            value,
        });
    }
    report.skipped_other += skipped;
    Ok(())
}
