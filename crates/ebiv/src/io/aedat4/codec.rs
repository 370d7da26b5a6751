//! Packet body decompression for AEDAT 4.0 (formats.md §9): each compressed body is one
//! complete LZ4 frame or ZSTD frame (frame formats, not raw blocks).
//!
//! The decompressor is created once per file and reused for every packet: the LZ4 frame
//! decoder keeps its block buffers, the ZSTD context is reset between frames, and the output
//! buffer keeps its capacity, so steady-state decoding allocates nothing. Output is capped,
//! so a hostile file cannot make the reader allocate without bound.

use lz4_flex::frame::FrameDecoder;
use std::io::{BufRead, Read};
use zstd::zstd_safe;

/// The IOHeader `compression` enum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Compression {
    None,
    Lz4,
    Lz4High,
    Zstd,
    ZstdHigh,
}

impl Compression {
    pub(super) fn from_code(code: i32) -> Option<Self> {
        Some(match code {
            0 => Compression::None,
            1 => Compression::Lz4,
            2 => Compression::Lz4High,
            3 => Compression::Zstd,
            4 => Compression::ZstdHigh,
            _ => return None,
        })
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            Compression::None => "NONE",
            Compression::Lz4 => "LZ4",
            Compression::Lz4High => "LZ4_HIGH",
            Compression::Zstd => "ZSTD",
            Compression::ZstdHigh => "ZSTD_HIGH",
        }
    }
}

/// Why a body could not be decompressed.
#[derive(Debug)]
pub(super) enum DecodeError {
    /// The body is not a valid frame; the packet can be skipped.
    Invalid(String),
    /// The decompressed body would exceed the cap; the file is not to be trusted further.
    TooLarge(usize),
}

/// The compressed bytes of one packet, read by the LZ4 frame decoder. Records whether the
/// decoder asked for more bytes than the packet holds (a frame cut short).
#[derive(Default)]
struct PacketBytes {
    data: Vec<u8>,
    len: usize,
    pos: usize,
    starved: bool,
}

impl Read for PacketBytes {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let avail = self.data.get(self.pos..self.len).unwrap_or(&[]);
        if avail.is_empty() && !buf.is_empty() {
            self.starved = true;
            return Ok(0);
        }
        let n = avail.len().min(buf.len());
        buf[..n].copy_from_slice(&avail[..n]);
        self.pos += n;
        Ok(n)
    }
}

enum Codec {
    None,
    Lz4(Box<FrameDecoder<PacketBytes>>),
    Zstd(zstd_safe::DCtx<'static>),
}

/// Reusable decompressor for one file's packets.
pub(super) struct Decompressor {
    codec: Codec,
    /// Compressed input (for NONE and ZSTD; LZ4 keeps it inside its decoder).
    input: Vec<u8>,
    /// Decompressed output.
    output: Vec<u8>,
    /// Largest decompressed body accepted.
    cap: usize,
    /// Block mode and maximum block size of the last LZ4 frame decoded.
    lz4_settings: Option<[u8; 6]>,
}

impl Decompressor {
    pub(super) fn new(compression: Compression, cap: usize) -> Self {
        let codec = match compression {
            Compression::None => Codec::None,
            Compression::Lz4 | Compression::Lz4High => {
                Codec::Lz4(Box::new(FrameDecoder::new(PacketBytes::default())))
            }
            Compression::Zstd | Compression::ZstdHigh => Codec::Zstd(zstd_safe::DCtx::create()),
        };
        Decompressor {
            codec,
            input: Vec::new(),
            output: Vec::new(),
            cap,
            lz4_settings: None,
        }
    }

    /// A buffer of `size` bytes to read the next compressed body into.
    pub(super) fn input_buffer(&mut self, size: usize) -> &mut [u8] {
        let buf = match &mut self.codec {
            Codec::Lz4(dec) => {
                let bytes = dec.get_mut();
                bytes.len = size;
                bytes.pos = 0;
                bytes.starved = false;
                &mut bytes.data
            }
            Codec::None | Codec::Zstd(_) => &mut self.input,
        };
        if buf.len() < size {
            buf.resize(size, 0);
        }
        &mut buf[..size]
    }

    /// Decompress the `size` bytes last written to [`Self::input_buffer`]. Returns the body
    /// and how many compressed bytes followed the end of the frame (normally 0).
    pub(super) fn decompress(&mut self, size: usize) -> Result<(&[u8], usize), DecodeError> {
        match &mut self.codec {
            Codec::None => {
                if size > self.cap {
                    return Err(DecodeError::TooLarge(size));
                }
                Ok((self.input.get(..size).unwrap_or(&[]), 0))
            }
            Codec::Lz4(dec) => {
                let packet = dec.get_ref();
                let input = packet.data.get(..packet.len).unwrap_or(&[]);
                if let Some((len, trailing)) =
                    super::lz4_direct::decompress_frame(input, &mut self.output, self.cap)?
                {
                    return Ok((&self.output[..len], trailing));
                }
                // lz4_flex sizes its block buffers for the first frame it decodes and expects
                // later frames to use the same block size and mode; DV writes every packet
                // alike, so the decoder is only replaced when they change.
                let settings = lz4_settings(dec.get_ref());
                if self.lz4_settings != Some(settings) {
                    reset(dec);
                    self.lz4_settings = Some(settings);
                }
                let result = lz4_frame(dec, &mut self.output, self.cap);
                let bytes = dec.get_ref();
                let trailing = bytes.len.saturating_sub(bytes.pos);
                if result.is_err() || trailing > 0 {
                    // The frame decoder may be mid-frame: start the next packet afresh.
                    reset(dec);
                    self.lz4_settings = None;
                }
                result.map(|()| (self.output.as_slice(), trailing))
            }
            Codec::Zstd(dctx) => {
                let input = self.input.get(..size).unwrap_or(&[]);
                let trailing = zstd_frame(dctx, input, &mut self.output, self.cap)?;
                Ok((self.output.as_slice(), trailing))
            }
        }
    }
}

/// The magic number (standard or legacy frame), block-independence flag (FLG bit 5) and
/// maximum block size (BD bits 6–4) of the LZ4 frame held by `bytes`.
fn lz4_settings(bytes: &PacketBytes) -> [u8; 6] {
    let byte = |i: usize| {
        if i < bytes.len {
            bytes.data.get(i).copied().unwrap_or(0)
        } else {
            0
        }
    };
    [
        byte(0),
        byte(1),
        byte(2),
        byte(3),
        byte(4) & 0x20,
        byte(5) & 0x70,
    ]
}

/// Replace `dec` by a fresh decoder over the same input buffer.
fn reset(dec: &mut Box<FrameDecoder<PacketBytes>>) {
    let old = std::mem::replace(dec, Box::new(FrameDecoder::new(PacketBytes::default())));
    **dec = FrameDecoder::new(old.into_inner());
}

/// Decompress one LZ4 frame (LZ4 frame format, <https://github.com/lz4/lz4/blob/dev/doc/lz4_Frame_format.md>)
/// into `out`, block by block, refusing more than `cap` bytes.
fn lz4_frame(
    dec: &mut FrameDecoder<PacketBytes>,
    out: &mut Vec<u8>,
    cap: usize,
) -> Result<(), DecodeError> {
    out.clear();
    loop {
        let chunk = dec
            .fill_buf()
            .map_err(|e| DecodeError::Invalid(format!("LZ4 frame: {e}")))?;
        if chunk.is_empty() {
            break;
        }
        if out.len() + chunk.len() > cap {
            return Err(DecodeError::TooLarge(out.len() + chunk.len()));
        }
        out.extend_from_slice(chunk);
        let n = chunk.len();
        dec.consume(n);
    }
    if dec.get_ref().starved {
        return Err(DecodeError::Invalid(
            "LZ4 frame ends before its end mark (cut short)".into(),
        ));
    }
    Ok(())
}

/// Decompress one ZSTD frame (RFC 8878) from `input` into `out`, refusing more than `cap`
/// bytes. Returns how many input bytes followed the frame.
fn zstd_frame(
    dctx: &mut zstd_safe::DCtx<'static>,
    input: &[u8],
    out: &mut Vec<u8>,
    cap: usize,
) -> Result<usize, DecodeError> {
    let invalid = |code: usize| {
        DecodeError::Invalid(format!("ZSTD frame: {}", zstd_safe::get_error_name(code)))
    };
    out.clear();
    dctx.reset(zstd_safe::ResetDirective::SessionOnly)
        .map_err(invalid)?;
    let expected = match zstd_safe::get_frame_content_size(input) {
        Ok(Some(n)) if n > cap as u64 => return Err(DecodeError::TooLarge(n as usize)),
        Ok(Some(n)) => n as usize,
        _ => input.len().saturating_mul(4),
    };
    out.reserve(expected.clamp(1024, cap.max(1024)));
    let mut src = zstd_safe::InBuffer::around(input);
    loop {
        if out.len() == out.capacity() {
            if out.len() >= cap {
                return Err(DecodeError::TooLarge(out.len() + 1));
            }
            let more = out.len().max(1 << 16).min(cap - out.len());
            out.reserve_exact(more);
        }
        let len = out.len();
        let hint = {
            let mut dst = zstd_safe::OutBuffer::around_pos(out, len);
            dctx.decompress_stream(&mut dst, &mut src)
                .map_err(invalid)?
        };
        if hint == 0 {
            return Ok(input.len() - src.pos());
        }
        if src.pos() == input.len() && out.len() < out.capacity() {
            return Err(DecodeError::Invalid(
                "ZSTD frame ends before it is complete (cut short)".into(),
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn lz4(data: &[u8]) -> Vec<u8> {
        let mut enc = lz4_flex::frame::FrameEncoder::new(Vec::new());
        enc.write_all(data).unwrap();
        enc.finish().unwrap()
    }

    fn run(d: &mut Decompressor, compressed: &[u8]) -> Result<(Vec<u8>, usize), DecodeError> {
        d.input_buffer(compressed.len()).copy_from_slice(compressed);
        d.decompress(compressed.len()).map(|(b, t)| (b.to_vec(), t))
    }

    #[test]
    fn lz4_frames_in_a_row_reuse_the_decoder() {
        let mut d = Decompressor::new(Compression::Lz4, 1 << 20);
        for n in [10usize, 100_000, 0, 70_000] {
            let data: Vec<u8> = (0..n).map(|i| (i * 7 % 251) as u8).collect();
            let (out, trailing) = run(&mut d, &lz4(&data)).unwrap();
            assert_eq!(out, data);
            assert_eq!(trailing, 0);
        }
    }

    #[test]
    fn lz4_block_modes_and_sizes_may_change_between_frames() {
        use lz4_flex::frame::{BlockMode, BlockSize, FrameInfo};
        let mut d = Decompressor::new(Compression::Lz4, 1 << 24);
        let data: Vec<u8> = (0..3_000_000).map(|i| ((i / 7) % 256) as u8).collect();
        for (mode, size) in [
            (BlockMode::Linked, BlockSize::Max64KB),
            (BlockMode::Linked, BlockSize::Max64KB),
            (BlockMode::Independent, BlockSize::Max4MB),
            (BlockMode::Linked, BlockSize::Max256KB),
            (BlockMode::Independent, BlockSize::Max64KB),
            (BlockMode::Linked, BlockSize::Max1MB),
        ] {
            let info = FrameInfo::new().block_mode(mode).block_size(size);
            let mut enc = lz4_flex::frame::FrameEncoder::with_frame_info(info, Vec::new());
            enc.write_all(&data).unwrap();
            let (out, _) = run(&mut d, &enc.finish().unwrap()).unwrap();
            assert!(out == data, "{mode:?} {size:?}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]

        /// Frames of changing settings, some damaged, through one decompressor: damaged ones
        /// fail cleanly (never a panic, not even a debug assertion of the frame decoder) and
        /// intact ones still decode exactly.
        #[test]
        fn damaged_lz4_frames_never_panic(
            frames in proptest::collection::vec(
                (0usize..4, proptest::bool::ANY, 0usize..200_000, proptest::collection::vec((0usize..1 << 20, 1u8..=255), 0..4)),
                1..6,
            )
        ) {
            use lz4_flex::frame::{BlockMode, BlockSize, FrameInfo};
            let mut d = Decompressor::new(Compression::Lz4, 1 << 22);
            for (size, linked, len, flips) in frames {
                let size = [BlockSize::Max64KB, BlockSize::Max256KB, BlockSize::Max1MB, BlockSize::Max4MB][size];
                let mode = if linked { BlockMode::Linked } else { BlockMode::Independent };
                let data: Vec<u8> = (0..len).map(|i| ((i / 3) % 251) as u8).collect();
                let info = FrameInfo::new().block_mode(mode).block_size(size).block_checksums(true);
                let mut enc = lz4_flex::frame::FrameEncoder::with_frame_info(info, Vec::new());
                enc.write_all(&data).unwrap();
                let mut frame = enc.finish().unwrap();
                let n = frame.len();
                for &(at, x) in &flips {
                    frame[at % n] ^= x;
                }
                let result = run(&mut d, &frame);
                if flips.is_empty() {
                    proptest::prop_assert!(result.unwrap().0 == data);
                }
            }
        }
    }

    #[test]
    fn lz4_cut_short_and_recovery() {
        let mut d = Decompressor::new(Compression::Lz4, 1 << 20);
        let data: Vec<u8> = (0..200_000).map(|i| (i % 13) as u8).collect();
        let frame = lz4(&data);
        for cut in [5, 7, 20, frame.len() / 2, frame.len() - 4, frame.len() - 1] {
            assert!(
                matches!(run(&mut d, &frame[..cut]), Err(DecodeError::Invalid(_))),
                "cut at {cut}"
            );
            let (out, _) = run(&mut d, &frame).unwrap();
            assert_eq!(out, data, "decoder recovers after a frame cut at {cut}");
        }
    }

    #[test]
    fn caps_are_enforced() {
        let data = vec![0u8; 300_000];
        let mut d = Decompressor::new(Compression::Lz4, 100_000);
        assert!(matches!(
            run(&mut d, &lz4(&data)),
            Err(DecodeError::TooLarge(_))
        ));
        let mut z = Decompressor::new(Compression::Zstd, 100_000);
        let compressed = zstd::bulk::compress(&data, 3).unwrap();
        assert!(matches!(
            run(&mut z, &compressed),
            Err(DecodeError::TooLarge(_))
        ));
        let mut streamed = Vec::new();
        {
            let mut enc = zstd::stream::write::Encoder::new(&mut streamed, 1).unwrap();
            enc.write_all(&data).unwrap();
            enc.finish().unwrap();
        }
        assert!(matches!(
            run(&mut z, &streamed),
            Err(DecodeError::TooLarge(_))
        ));
    }

    #[test]
    fn zstd_with_and_without_content_size() {
        let mut z = Decompressor::new(Compression::Zstd, 1 << 22);
        let data: Vec<u8> = (0..1_000_000).map(|i| (i * 31 % 253) as u8).collect();
        let (out, trailing) = run(&mut z, &zstd::bulk::compress(&data, 3).unwrap()).unwrap();
        assert_eq!((out == data, trailing), (true, 0));
        let mut streamed = Vec::new();
        {
            let mut enc = zstd::stream::write::Encoder::new(&mut streamed, 1).unwrap();
            enc.include_contentsize(false).unwrap();
            enc.write_all(&data).unwrap();
            enc.finish().unwrap();
        }
        let (out, _) = run(&mut z, &streamed).unwrap();
        assert_eq!(out, data);
        let half = &streamed[..streamed.len() / 2];
        assert!(matches!(run(&mut z, half), Err(DecodeError::Invalid(_))));
        assert!(matches!(
            run(&mut z, b"garbage!"),
            Err(DecodeError::Invalid(_))
        ));
        let (out, _) = run(&mut z, &streamed).unwrap();
        assert_eq!(out, data);
    }
}
