//! Fuzz target: `cargo fuzz run lz4_block -- -max_total_time=180`.
//!
//! The AEDAT 4.0 reader's LZ4 block decoder against lz4_flex: on any bytes it must not
//! panic, and whenever lz4_flex decodes them, it must give the same content. The bytes are
//! also compressed (with the first part as a dictionary) and must decompress to themselves.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((&split, rest)) = data.split_first() else { return };
    let (dictionary, block) = rest.split_at((split as usize * 4).min(rest.len()));
    let limit = 4 * block.len() + 64;
    let ours = ebiv::io::lz4_block_for_fuzzing(block, dictionary, limit);
    let mut theirs = vec![0u8; limit];
    if let Ok(n) = lz4_flex::block::decompress_into_with_dict(block, &mut theirs, dictionary) {
        assert_eq!(ours.as_deref(), Some(&theirs[..n]), "lz4_flex decodes this block");
    }
    let compressed = lz4_flex::block::compress_with_dict(block, dictionary);
    let back = ebiv::io::lz4_block_for_fuzzing(&compressed, dictionary, block.len());
    assert_eq!(back.as_deref(), Some(block), "round trip");
});
