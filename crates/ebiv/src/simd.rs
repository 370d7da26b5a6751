//! Run-time choice of wider vector instructions.
//!
//! The release build targets every x86-64 processor (SSE2: two `f64` or four `f32` lanes per
//! instruction). The hottest kernels, whose loops are written as fixed-width lane arrays or
//! as straight-line code the compiler vectorises, are compiled a second time with AVX2
//! enabled (four `f64` or eight `f32` lanes, and 64-bit integer comparisons, which SSE2
//! lacks), and that build is chosen where the processor has AVX2. Both builds perform the
//! same IEEE operations in the same order (Rust never fuses a multiply and an add on its
//! own), so results are bit-identical on every machine, as the determinism rule of the
//! design requires.

/// True where the AVX2 builds of the kernels may run: x86-64 processors with AVX2, detected
/// at run time (the answer is cached by the standard library).
pub(crate) fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::arch::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    false
}
