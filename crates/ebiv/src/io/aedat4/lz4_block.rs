//! Decompression of one LZ4 block (LZ4 block format,
//! <https://github.com/lz4/lz4/blob/dev/doc/lz4_Block_format.md>), in safe Rust.
//!
//! A block is a series of sequences: a token byte (high nibble: literal length, low nibble:
//! match length − 4, each extended by following bytes while they are 255 when the nibble is 15),
//! the literals, a 2-byte little-endian offset, and the match, a copy of `length` bytes from
//! `offset` bytes back in the output. The last sequence has literals only.
//!
//! Event packets compress to many short sequences (a few literals, matches of 5–18 bytes at
//! offsets of whole 16-byte events), so the cost per sequence is what matters. The usual
//! sequence (at most 14 literals, a match of at most 18 bytes at an offset of 16 or more, away
//! from both ends) takes a fast path with one check of input and output room for the whole
//! sequence; it and the general path copy literals and matches in fixed 16-byte chunks ("wild
//! copy"): the last chunk may write up to 15 bytes past the end of the sequence, which the
//! next sequence overwrites, or into the [`SLACK`] bytes the output keeps after its limit.
//! Matches at shorter offsets overlap their own output and are copied by doubling the
//! repeated pattern. Damaged input gives an error, never an access out of bounds.

/// Bytes the output must hold beyond the decompression limit for the chunked copies.
pub(crate) const SLACK: usize = 16;

/// Width of one chunked copy.
const CHUNK: usize = 16;

/// Why a block could not be decompressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum BlockError {
    /// The block ends inside a sequence.
    Truncated,
    /// A match refers to data before the start of the window (or offset 0).
    BadOffset,
    /// The content would exceed the limit (the frame's maximum block size).
    TooLong,
}

impl std::fmt::Display for BlockError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BlockError::Truncated => "block ends inside a sequence",
            BlockError::BadOffset => "match offset points before the available data",
            BlockError::TooLong => "block decompresses to more than the maximum block size",
        })
    }
}

/// Decompress the block `input` into `out`, starting at `start` and ending at or before
/// `limit`. Matches may reach back to `window_start` (`start` for an independent block, the
/// start of the earlier content for a linked one). `out` must be at least `limit + SLACK`
/// long; bytes from the end of the content up to `limit + SLACK` may be overwritten. Returns
/// where the content ends.
pub(crate) fn decompress(
    input: &[u8],
    out: &mut [u8],
    window_start: usize,
    start: usize,
    limit: usize,
) -> Result<usize, BlockError> {
    if window_start > start || start > limit || limit + SLACK > out.len() {
        return Err(BlockError::TooLong);
    }
    let out = &mut out[..limit + SLACK];
    let mut i = 0usize;
    let mut d = start;
    loop {
        let &token = input.get(i).ok_or(BlockError::Truncated)?;
        i += 1;

        // The usual sequence, far from both ends: at most 14 literals and a match of at most
        // 18 bytes at an offset of 16 or more. One check covers the literal chunk, the offset
        // and the match's two chunks.
        let (lit, len) = ((token >> 4) as usize, (token & 15) as usize + 4);
        if let (true, Some(head), Some(room)) = (
            lit < 15 && len < 19 && d + 2 * CHUNK + 3 <= limit,
            input.get(i..i + CHUNK + 2),
            out.get_mut(d..d + 3 * CHUNK),
        ) {
            room[..CHUNK].copy_from_slice(&head[..CHUNK]);
            let offset = u16::from_le_bytes([head[lit], head[lit + 1]]) as usize;
            i += lit + 2;
            d += lit;
            if offset >= CHUNK && offset <= d - window_start {
                let src = d - offset;
                let chunk: [u8; CHUNK] = out[src..src + CHUNK].try_into().expect("16 bytes");
                out[d..d + CHUNK].copy_from_slice(&chunk);
                if len > CHUNK {
                    let chunk: [u8; CHUNK] = out[src + CHUNK..src + 2 * CHUNK]
                        .try_into()
                        .expect("16 bytes");
                    out[d + CHUNK..d + 2 * CHUNK].copy_from_slice(&chunk);
                }
                d += len;
                continue;
            }
            if offset == 0 || offset > d - window_start {
                return Err(BlockError::BadOffset);
            }
            overlapping_match(out, d - offset, d, len);
            d += len;
            continue;
        }

        // Literals.
        let mut lit = (token >> 4) as usize;
        if lit == 15 {
            lit += extension(input, &mut i)?;
        }
        let lit_end = d.checked_add(lit).ok_or(BlockError::TooLong)?;
        if lit_end > limit {
            return Err(BlockError::TooLong);
        }
        match input.get(i..i + CHUNK) {
            // `lit <= CHUNK`: one chunk, possibly reading and writing a little more than
            // needed (`d + CHUNK <= limit + SLACK` as `d <= lit_end <= limit`).
            Some(chunk) if lit <= CHUNK => out[d..d + CHUNK].copy_from_slice(chunk),
            _ => {
                let src = i
                    .checked_add(lit)
                    .and_then(|end| input.get(i..end))
                    .ok_or(BlockError::Truncated)?;
                out[d..lit_end].copy_from_slice(src);
            }
        }
        i += lit;
        d = lit_end;
        if i == input.len() {
            return Ok(d);
        }

        // Match.
        let offset = match input.get(i..i + 2) {
            Some(&[a, b]) => u16::from_le_bytes([a, b]) as usize,
            _ => return Err(BlockError::Truncated),
        };
        i += 2;
        let mut len = (token & 15) as usize;
        if len == 15 {
            len += extension(input, &mut i)?;
        }
        len += 4;
        if offset == 0 || offset > d - window_start {
            return Err(BlockError::BadOffset);
        }
        let end = d.checked_add(len).ok_or(BlockError::TooLong)?;
        if end > limit {
            return Err(BlockError::TooLong);
        }
        let src = d - offset;
        if offset >= CHUNK {
            // Each chunk reads only bytes before the one it writes: no overlap. The last chunk
            // ends before `end + CHUNK <= limit + SLACK`.
            out.copy_within(src..src + CHUNK, d);
            let mut k = CHUNK;
            while k < len {
                out.copy_within(src + k..src + k + CHUNK, d + k);
                k += CHUNK;
            }
        } else {
            overlapping_match(out, src, d, len);
        }
        d = end;
    }
}

/// The bytes added to a length whose nibble was 15: a run of 255s and the byte ending it.
#[inline(always)]
fn extension(input: &[u8], i: &mut usize) -> Result<usize, BlockError> {
    let mut sum = 0usize;
    loop {
        let &b = input.get(*i).ok_or(BlockError::Truncated)?;
        *i += 1;
        sum += b as usize;
        if b != 255 {
            return Ok(sum);
        }
    }
}

/// A match whose offset `d - src` is shorter than its length: the output repeats the
/// `d - src` bytes before `d`. Copies the pattern, then ever longer runs of whole periods.
#[cold]
fn overlapping_match(out: &mut [u8], src: usize, d: usize, len: usize) {
    let period = d - src;
    let mut done = 0;
    while done < len {
        // `done` is a whole number of periods, so `src..` holds what goes at `d + done..`,
        // and the `period + done` bytes from `src` are all written already.
        let n = (period + done).min(len - done);
        out.copy_within(src..src + n, d + done);
        done += n;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Our decompression of an independent block, into a buffer of exactly `limit + SLACK`.
    fn ours(block: &[u8], limit: usize) -> Result<Vec<u8>, BlockError> {
        let mut out = vec![0u8; limit + SLACK];
        let end = decompress(block, &mut out, 0, 0, limit)?;
        out.truncate(end);
        Ok(out)
    }

    /// Compressible data: runs, repeats at every distance up to a few hundred bytes, noise.
    fn compressible(seed: u64, n: usize) -> Vec<u8> {
        let mut state = seed | 1;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut data = Vec::with_capacity(n);
        while data.len() < n {
            let r = next();
            let len = (r >> 8) as usize % 40 + 1;
            match r % 4 {
                0 if !data.is_empty() => {
                    let back = ((r >> 16) as usize % data.len().min(300)) + 1;
                    for _ in 0..len {
                        data.push(data[data.len() - back]);
                    }
                }
                1 => data.extend(std::iter::repeat_n((r >> 24) as u8, len)),
                _ => data.extend((0..len).map(|_| next() as u8)),
            }
        }
        data.truncate(n);
        data
    }

    #[test]
    fn sixteen_byte_events_round_trip() {
        let mut data = Vec::new();
        for k in 0..5000u64 {
            data.extend_from_slice(&(1_700_000_000_000_000 + k * 3).to_le_bytes());
            data.extend_from_slice(&((k * 37 % 1280) as u16).to_le_bytes());
            data.extend_from_slice(&((k * 11 % 720) as u16).to_le_bytes());
            data.extend_from_slice(&[(k % 3 == 0) as u8, 0, 0, 0]);
        }
        let block = lz4_flex::block::compress(&data);
        assert_eq!(ours(&block, data.len()).unwrap(), data);
        assert_eq!(
            ours(&block, data.len() - 1),
            Err(BlockError::TooLong),
            "one byte short of room"
        );
    }

    #[test]
    fn every_short_offset_and_length() {
        // Hand-made blocks: `a` literals then a match of `len` at offset `off <= a`.
        for a in 1..20usize {
            for off in 1..=a {
                for len in 4..40usize {
                    let lits: Vec<u8> = (0..a as u8).map(|v| v.wrapping_mul(7) + 1).collect();
                    let mut block = vec![((a.min(15) as u8) << 4) | (len - 4).min(15) as u8];
                    if a >= 15 {
                        block.push((a - 15) as u8);
                    }
                    block.extend_from_slice(&lits);
                    block.extend_from_slice(&(off as u16).to_le_bytes());
                    if len - 4 >= 15 {
                        block.push((len - 4 - 15) as u8);
                    }
                    block.push(0x10);
                    block.push(0xEE);
                    let mut expected = lits.clone();
                    for _ in 0..len {
                        expected.push(expected[expected.len() - off]);
                    }
                    expected.push(0xEE);
                    assert_eq!(
                        ours(&block, expected.len()).unwrap(),
                        expected,
                        "{a} {off} {len}"
                    );
                }
            }
        }
    }

    #[test]
    fn damage_is_an_error() {
        assert_eq!(ours(&[], 10), Err(BlockError::Truncated));
        assert_eq!(ours(&[0x50, 1, 2], 10), Err(BlockError::Truncated));
        // A match at offset 2 with only 1 byte of output before it.
        assert_eq!(
            ours(&[0x10, 9, 2, 0, 0x00], 100),
            Err(BlockError::BadOffset)
        );
        assert_eq!(ours(&[0x10, 9, 0, 0], 100), Err(BlockError::BadOffset));
        // Extension bytes that never end.
        assert_eq!(ours(&[0xF0, 255, 255], 1000), Err(BlockError::Truncated));
        // A window that starts at `start`: no reference into the earlier content.
        let mut out = vec![7u8; 64];
        assert_eq!(
            decompress(&[0x10, 9, 2, 0, 0x00], &mut out, 10, 10, 40),
            Err(BlockError::BadOffset)
        );
        assert_eq!(decompress(&[0x00, 2, 0, 0x00], &mut out, 0, 10, 40), Ok(14));
        assert_eq!(&out[10..14], &[7, 7, 7, 7]);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        #[test]
        fn random_data_round_trips(data in proptest::collection::vec(any::<u8>(), 0..5000)) {
            let block = lz4_flex::block::compress(&data);
            prop_assert_eq!(ours(&block, data.len()).unwrap(), data);
        }

        #[test]
        fn compressible_data_round_trips(seed in any::<u64>(), n in 0usize..70_000) {
            let data = compressible(seed, n);
            let block = lz4_flex::block::compress(&data);
            prop_assert_eq!(ours(&block, data.len()).unwrap(), data);
        }

        /// Linked blocks: the second block refers into the first one's content.
        #[test]
        fn a_dictionary_before_the_block_is_used(seed in any::<u64>(), n in 1usize..20_000, m in 0usize..20_000) {
            let data = compressible(seed, n + m);
            let (dict, rest) = data.split_at(n);
            let block = lz4_flex::block::compress_with_dict(rest, dict);
            let mut out = vec![0u8; n + m + SLACK];
            out[..n].copy_from_slice(dict);
            let end = decompress(&block, &mut out, 0, n, n + m).unwrap();
            prop_assert_eq!(end, n + m);
            prop_assert_eq!(&out[..end], &data[..]);
        }

        /// Damaged blocks: an error or some content, never a panic; and whenever lz4_flex
        /// accepts the damaged block, the content is the same.
        #[test]
        fn damage_never_panics(
            seed in any::<u64>(),
            n in 0usize..20_000,
            flips in proptest::collection::vec((any::<usize>(), 1u8..=255), 1..6),
            cut in any::<usize>(),
            slack in 0usize..100,
        ) {
            let data = compressible(seed, n);
            let mut block = lz4_flex::block::compress(&data);
            if !block.is_empty() {
                let len = block.len();
                for &(at, x) in &flips {
                    block[at % len] ^= x;
                }
                block.truncate(len - cut % (len.min(8) + 1) * (cut % 3 == 0) as usize);
            }
            let limit = n + slack;
            let mut reference = vec![0u8; limit];
            let theirs = lz4_flex::block::decompress_into(&block, &mut reference);
            let result = ours(&block, limit);
            if let Ok(m) = theirs {
                prop_assert_eq!(result.unwrap(), &reference[..m]);
            }
        }

        /// Bytes that are not an LZ4 block at all.
        #[test]
        fn garbage_never_panics(block in proptest::collection::vec(any::<u8>(), 0..300), limit in 0usize..2000) {
            let _ = ours(&block, limit);
        }
    }
}
