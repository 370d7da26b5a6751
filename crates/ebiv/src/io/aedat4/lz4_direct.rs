//! The usual LZ4 frame of an AEDAT 4.0 packet decompressed block by block, by the block
//! decoder of [`super::lz4_block`], straight into one buffer (LZ4 frame format,
//! <https://github.com/lz4/lz4/blob/dev/doc/lz4_Frame_format.md>): no copy out of a frame
//! decoder's own buffers, and no zeroing of the output for every packet. Linked blocks find
//! their dictionary, the 64 KiB before them, in the same buffer.
//! Frames with checksums over blocks or content, a dictionary, or another magic number are
//! left to the general frame decoder.

use super::codec::DecodeError;
use super::lz4_block::{self, SLACK};

const MAGIC: u32 = 0x184D_2204;
/// Largest back-reference of an LZ4 block: the dictionary of a linked block.
const WINDOW: usize = 64 * 1024;

/// Decompress the frame at the start of `input` into `out`, whose whole length is usable room
/// (grown, never shrunk, so steady-state decoding writes into memory already touched).
/// Returns the content length and how many input bytes followed the frame, or `Ok(None)`
/// when the frame uses a feature left to the general decoder. Refuses content beyond `cap`.
pub(super) fn decompress_frame(
    input: &[u8],
    out: &mut Vec<u8>,
    cap: usize,
) -> Result<Option<(usize, usize)>, DecodeError> {
    let Some(frame) = Descriptor::parse(input) else {
        return Ok(None);
    };
    let cut_short =
        || DecodeError::Invalid("LZ4 frame ends before its end mark (cut short)".into());
    let mut pos = frame.header_len;
    let mut len = 0usize;
    loop {
        let word = input
            .get(pos..pos + 4)
            .ok_or_else(cut_short)?
            .try_into()
            .map(u32::from_le_bytes)
            .map_err(|_| cut_short())?;
        pos += 4;
        if word == 0 {
            break;
        }
        let size = (word & 0x7FFF_FFFF) as usize;
        if size > frame.max_block {
            return Err(DecodeError::Invalid(format!(
                "LZ4 frame: block of {size} bytes, more than the frame's maximum {}",
                frame.max_block
            )));
        }
        let block = input.get(pos..pos + size).ok_or_else(cut_short)?;
        pos += size;
        if out.len() < len + frame.max_block + SLACK {
            out.resize(len + frame.max_block + SLACK, 0);
        }
        let written = if word & 0x8000_0000 != 0 {
            out[len..len + size].copy_from_slice(block);
            size
        } else {
            let window_start = if frame.linked {
                len.saturating_sub(WINDOW)
            } else {
                len
            };
            lz4_block::decompress(block, out, window_start, len, len + frame.max_block)
                .map_err(|e| DecodeError::Invalid(format!("LZ4 frame: {e}")))?
                - len
        };
        len += written;
        if len > cap {
            return Err(DecodeError::TooLarge(len));
        }
    }
    if let Some(expected) = frame.content_size {
        if expected != len as u64 {
            return Err(DecodeError::Invalid(format!(
                "LZ4 frame: content of {len} bytes where the header says {expected}"
            )));
        }
    }
    Ok(Some((len, input.len() - pos)))
}

/// What the frame header says, for the frames handled here.
struct Descriptor {
    /// Magic number, descriptor and header checksum.
    header_len: usize,
    /// Blocks may refer to the 64 KiB before them.
    linked: bool,
    max_block: usize,
    content_size: Option<u64>,
}

impl Descriptor {
    /// The header of a standard frame (version 01) without block or content checksums and
    /// without a dictionary, with a valid header checksum; `None` for any other.
    fn parse(input: &[u8]) -> Option<Descriptor> {
        let magic = u32::from_le_bytes(input.get(..4)?.try_into().ok()?);
        let (&flags, &block_byte) = (input.get(4)?, input.get(5)?);
        let version = flags >> 6;
        let unsupported = 0x10 | 0x04 | 0x02 | 0x01; // block and content checksums, reserved, dictionary
        if magic != MAGIC || version != 1 || flags & unsupported != 0 || block_byte & 0x8F != 0 {
            return None;
        }
        let max_block = match block_byte >> 4 {
            4 => 64 << 10,
            5 => 256 << 10,
            6 => 1 << 20,
            7 => 4 << 20,
            _ => return None,
        };
        let has_size = flags & 0x08 != 0;
        let descriptor = input.get(4..if has_size { 14 } else { 6 })?;
        let checksum = *input.get(4 + descriptor.len())?;
        if checksum != (twox_hash::XxHash32::oneshot(0, descriptor) >> 8) as u8 {
            return None;
        }
        let content_size = has_size
            .then(|| descriptor[2..10].try_into().ok().map(u64::from_le_bytes))
            .flatten();
        Some(Descriptor {
            header_len: 5 + descriptor.len(),
            linked: flags & 0x20 == 0,
            max_block,
            content_size,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lz4_flex::frame::{BlockMode, BlockSize, FrameEncoder, FrameInfo};
    use std::io::{Read, Write};

    fn frame(data: &[u8], info: FrameInfo) -> Vec<u8> {
        let mut enc = FrameEncoder::with_frame_info(info, Vec::new());
        enc.write_all(data).unwrap();
        enc.finish().unwrap()
    }

    /// Compressible with long-range repeats (linked blocks use them), with stretches of
    /// noise that the encoder stores uncompressed.
    fn data(n: usize, seed: u64) -> Vec<u8> {
        let mut state = seed | 1;
        let mut noise = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state as u8
        };
        (0..n)
            .map(|i| match (i / 50_000) % 3 {
                0 => (i % 97) as u8,
                1 => noise(),
                _ => ((i * 31) % 251) as u8 ^ (noise() & 1),
            })
            .collect()
    }

    #[test]
    fn matches_the_general_decoder_for_every_block_mode_and_size() {
        for (k, mode) in [BlockMode::Linked, BlockMode::Independent]
            .into_iter()
            .enumerate()
        {
            for size in [BlockSize::Max64KB, BlockSize::Max256KB, BlockSize::Max1MB] {
                for n in [0usize, 1, 70_000, 300_000] {
                    let content = data(n, 7 + k as u64);
                    let info = FrameInfo::new()
                        .block_mode(mode)
                        .block_size(size)
                        .content_size(Some(n as u64).filter(|_| n % 2 == 0));
                    let mut bytes = frame(&content, info);
                    let mut general = Vec::new();
                    lz4_flex::frame::FrameDecoder::new(&bytes[..])
                        .read_to_end(&mut general)
                        .unwrap();
                    bytes.extend_from_slice(b"xyz");
                    let mut out = vec![0xAA; 5];
                    let (len, trailing) = decompress_frame(&bytes, &mut out, 1 << 30)
                        .unwrap()
                        .expect("a frame handled here");
                    assert_eq!(&out[..len], &general[..], "{mode:?} {size:?} {n}");
                    assert_eq!(trailing, 3);
                }
            }
        }
    }

    #[test]
    fn checksums_and_foreign_frames_go_to_the_general_decoder() {
        let content = data(1000, 3);
        let with_checksum = frame(&content, FrameInfo::new().content_checksum(true));
        let mut out = Vec::new();
        assert!(matches!(
            decompress_frame(&with_checksum, &mut out, 1 << 20),
            Ok(None)
        ));
        let mut bad_header = frame(&content, FrameInfo::new());
        bad_header[6] ^= 1; // the header checksum no longer matches
        assert!(matches!(
            decompress_frame(&bad_header, &mut out, 1 << 20),
            Ok(None)
        ));
        assert!(matches!(
            decompress_frame(b"\x04\x22", &mut out, 1 << 20),
            Ok(None)
        ));
    }

    #[test]
    fn damaged_frames_are_errors_not_panics() {
        let content = data(200_000, 5);
        let bytes = frame(&content, FrameInfo::new());
        let mut out = Vec::new();
        for cut in [8, 12, 1000, bytes.len() - 1] {
            assert!(matches!(
                decompress_frame(&bytes[..cut], &mut out, 1 << 30),
                Err(DecodeError::Invalid(_))
            ));
        }
        assert!(matches!(
            decompress_frame(&bytes, &mut out, 100_000),
            Err(DecodeError::TooLarge(_))
        ));
        // Every byte of the body flipped in turn: an error or some content, never a panic.
        let mut damaged = bytes.clone();
        for i in (7..damaged.len()).step_by(61) {
            damaged[i] ^= 0x5A;
            let _ = decompress_frame(&damaged, &mut out, 1 << 30);
            damaged[i] ^= 0x5A;
        }
    }
}
