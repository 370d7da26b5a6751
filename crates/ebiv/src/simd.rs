//! Run-time choice of wider vector instructions.
//!
//! The release build targets every x86-64 processor (SSE2: two `f64` or four `f32` lanes per
//! instruction). The hottest kernels, whose loops are written as fixed-width lane arrays or
//! as straight-line code the compiler vectorises, are compiled a second time with AVX2
//! enabled (four `f64` or eight `f32` lanes, and 64-bit integer comparisons, which SSE2
//! lacks), and that build is chosen where the processor has AVX2. Both builds perform the
//! same IEEE operations in the same order (Rust never fuses a multiply and an add on its
//! own), so results are bit-identical on every machine, as the determinism rule of the
//! design requires. Where the compiler vectorised lane arrays the wrong way, the lanes are
//! written out: [`Quad`] (four SSE lanes, every x86-64 processor) in the objective's
//! derivatives, and explicit AVX2 code for the motion vote's pair cells, the derivatives'
//! eight-lane footprint rows and the simulator's erf table (gathered coefficients), again with
//! the same operations per lane as the scalar code.

/// True where the AVX2 builds of the kernels may run: x86-64 processors with AVX2, detected
/// at run time (the answer is cached by the standard library).
pub(crate) fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::arch::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Ask the processor to bring the cache line of `value` into its caches, ahead of a use
/// whose address it could not foresee (an element of a table indexed by data). A hint only:
/// it changes no value, and does nothing off x86-64.
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: a prefetch reads nothing the program sees and cannot fault; the address is
        // that of a live value anyway.
        unsafe { _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// Four `f32` lanes: one SSE register on x86-64 (every x86-64 processor has SSE2), an array
/// elsewhere. For kernels whose lane arrays the compiler's vectoriser packs the wrong way
/// (across the accumulators instead of along the lanes, with a shuffle per value): written
/// with these, each line is one vector instruction. Every operation is the IEEE operation
/// per lane (no fused multiply-add), so the results are the bits of the same operations on
/// `[f32; 4]`, on every machine.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Quad(QuadLanes);

#[cfg(target_arch = "x86_64")]
type QuadLanes = std::arch::x86_64::__m128;
#[cfg(not(target_arch = "x86_64"))]
type QuadLanes = [f32; 4];

#[cfg(target_arch = "x86_64")]
impl Quad {
    /// All lanes +0.
    #[inline(always)]
    pub fn zero() -> Quad {
        // SAFETY: SSE is part of the x86-64 baseline (every x86-64 processor has it).
        Quad(unsafe { std::arch::x86_64::_mm_setzero_ps() })
    }

    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: f32) -> Quad {
        // SAFETY: SSE is part of the x86-64 baseline (every x86-64 processor has it).
        Quad(unsafe { std::arch::x86_64::_mm_set1_ps(v) })
    }

    /// The four values of `cells`.
    #[inline(always)]
    pub fn load(cells: &[f32; 4]) -> Quad {
        // SAFETY: `cells` is four readable `f32`; `loadu` takes any alignment.
        Quad(unsafe { std::arch::x86_64::_mm_loadu_ps(cells.as_ptr()) })
    }

    /// Write the lanes to `cells`.
    #[inline(always)]
    pub fn store(self, cells: &mut [f32; 4]) {
        // SAFETY: `cells` is four writable `f32`; `storeu` takes any alignment.
        unsafe { std::arch::x86_64::_mm_storeu_ps(cells.as_mut_ptr(), self.0) }
    }

    /// Lane-wise sum.
    #[inline(always)]
    pub fn add(self, other: Quad) -> Quad {
        // SAFETY: SSE is part of the x86-64 baseline (every x86-64 processor has it).
        Quad(unsafe { std::arch::x86_64::_mm_add_ps(self.0, other.0) })
    }

    /// Lane-wise product.
    #[inline(always)]
    pub fn mul(self, other: Quad) -> Quad {
        // SAFETY: SSE is part of the x86-64 baseline (every x86-64 processor has it).
        Quad(unsafe { std::arch::x86_64::_mm_mul_ps(self.0, other.0) })
    }

    /// The lanes as an array.
    #[inline(always)]
    pub fn to_array(self) -> [f32; 4] {
        let mut out = [0f32; 4];
        self.store(&mut out);
        out
    }
}

#[cfg(not(target_arch = "x86_64"))]
impl Quad {
    /// All lanes +0.
    #[inline(always)]
    pub fn zero() -> Quad {
        Quad([0.0; 4])
    }

    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: f32) -> Quad {
        Quad([v; 4])
    }

    /// The four values of `cells`.
    #[inline(always)]
    pub fn load(cells: &[f32; 4]) -> Quad {
        Quad(*cells)
    }

    /// Write the lanes to `cells`.
    #[inline(always)]
    pub fn store(self, cells: &mut [f32; 4]) {
        *cells = self.0;
    }

    /// Lane-wise sum.
    #[inline(always)]
    pub fn add(self, other: Quad) -> Quad {
        Quad(std::array::from_fn(|l| self.0[l] + other.0[l]))
    }

    /// Lane-wise product.
    #[inline(always)]
    pub fn mul(self, other: Quad) -> Quad {
        Quad(std::array::from_fn(|l| self.0[l] * other.0[l]))
    }

    /// The lanes as an array.
    #[inline(always)]
    pub fn to_array(self) -> [f32; 4] {
        self.0
    }
}
