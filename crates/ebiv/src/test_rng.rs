//! The pseudo-random numbers of the unit tests: a 64-bit xorshift generator (Marsaglia 2003,
//! J. Stat. Softw. 8(14), shifts 13, 7, 17), the same stream on every machine.

/// The stream of a 64-bit xorshift generator started at `seed` (not zero, or the stream is
/// all zeros).
pub(crate) fn xorshift(seed: u64) -> impl FnMut() -> u64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}
