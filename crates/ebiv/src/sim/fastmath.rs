//! Fast, deterministic elementary functions for the simulator's inner loops: `exp`, `ln` and
//! `erf` ([`Erf`]), evaluated with plain additions and multiplications (no FMA, no platform
//! library), so that they give the same bits on every machine.
//!
//! Accuracy (checked against the correctly rounded values in the tests below):
//! * [`exp`]: relative error below 4.5e-16 (2 ulp), the result of a 64-entry table of
//!   `2^(j/64)` times a degree-5 Taylor polynomial on `|r| ≤ ln 2/128` (truncation 4e-17);
//!   the method of Tang (ACM TOMS 15, 1989) as used by glibc and musl.
//! * [`ln`]: absolute error below 3e-16 + 2.3e-16·|ln x| (about 1 ulp), from a table of the
//!   reciprocals of the nodes `1 + j/128` and a degree-6 series of `ln(1 + r)`, `|r| ≤ 2^-8`
//!   (truncation 2e-18); exact at 1.
//! * [`Erf::eval`]: absolute error below 5e-16, a degree-7 Taylor expansion about the nearest
//!   of the nodes `j/32` on `[0, 6]` (truncation below 1e-16; `1 − erf(6) = 2e-17`), with node
//!   coefficients `erf(x_j)` and `erf⁽ⁿ⁾(x_j)/n! = (2/√π)·(−1)ⁿ⁻¹·H_{n−1}(x_j)·e^{−x_j²}/n!`
//!   (Hermite polynomials) computed once from `libm`.
//!
//! These errors are far below anything the sensor model resolves: its threshold levels carry
//! a tie tolerance of 1e-9 ln units and crossing times are root-found to 1e-7 µs.

use std::sync::OnceLock;

/// `64/ln 2`.
const INV_LN2_64: f64 = 92.332_482_616_893_66;
/// `ln 2/64`, split so that `k·LN2_64_HI` is exact for `|k| < 2^20`.
const LN2_64_HI: f64 = 0.010_830_424_695_086_549;
const LN2_64_LO: f64 = 1.162_596_423_439_437e-12;
/// `ln 2`, split so that `e·LN2_HI` is exact for every binary exponent `e`.
const LN2_HI: f64 = 0.693_147_180_485_539_1;
const LN2_LO: f64 = 7.440_617_110_012_397e-11;
/// `1.5·2^52`: adding it rounds to an integer held in the low mantissa bits.
const SHIFT: f64 = 6_755_399_441_055_744.0;

/// `e^x`. Relative error < 4.5e-16 (2 ulp) for |x| < 708 (< 9e-16 up to 709.78); 0 for
/// x ≤ −708, `+∞` above 709.78, NaN for NaN.
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    // One comparison: NaN is not in range either.
    let in_range = x.abs() < 708.0;
    if !in_range {
        return exp_edge(x);
    }
    let kd = x * INV_LN2_64 + SHIFT;
    let ki = kd.to_bits();
    let kd = kd - SHIFT;
    let r = (x - kd * LN2_64_HI) - kd * LN2_64_LO;
    let j = (ki & 63) as usize;
    // The low 52 bits of `ki` hold 2^51 + k; e^x = 2^(k >> 6) · 2^(j/64) · e^r.
    let k = (ki & ((1 << 52) - 1)) as i64 - (1 << 51);
    let e = (k >> 6) as u64;
    let scale = f64::from_bits(EXP2_TABLE[j].to_bits().wrapping_add(e << 52));
    let r2 = r * r;
    let p = r + r2 * (0.5 + r * (1.0 / 6.0) + r2 * (1.0 / 24.0 + r * (1.0 / 120.0)));
    scale + scale * p
}

#[cold]
fn exp_edge(x: f64) -> f64 {
    if x.is_nan() {
        x
    } else if x > 0.0 {
        if x < 709.78 {
            // Still finite: e^x = (e^(x/2))², relative error 2·2 ulp.
            let h = exp(0.5 * x);
            h * h
        } else {
            f64::INFINITY
        }
    } else {
        0.0
    }
}

/// `ln x`. Absolute error < 3e-16 + 2.3e-16·|ln x| (about 1 ulp) for positive normal `x`; other inputs
/// (0, subnormal, negative, ∞, NaN) go to `f64::ln`.
#[inline(always)]
pub fn ln(x: f64) -> f64 {
    let bits = x.to_bits();
    let biased = bits >> 52;
    // `biased` outside 1..=0x7FE (zero, subnormal, negative, ∞, NaN) in one comparison.
    if biased.wrapping_sub(1) >= 0x7FE {
        return x.ln();
    }
    let e = biased as i64 - 1023;
    ln_of_normal(bits, e as f64)
}

/// `ln x` of a positive normal `x` given by its `bits` and unbiased exponent `ef`: the
/// common part of [`ln`] and [`ln_lanes`].
#[inline(always)]
fn ln_of_normal(bits: u64, ef: f64) -> f64 {
    let mantissa = bits & ((1 << 52) - 1);
    // The nearest node 1 + j/128 to the mantissa m ∈ [1, 2).
    let j = ((mantissa + (1 << 44)) >> 45) as usize;
    let m = f64::from_bits(mantissa | (1023 << 52));
    // ln x = e·ln 2 + ln(1/inv) + ln(m·inv), with m·inv within 2^-8 of 1 (exactly 1 at a
    // node, so that ln 1 = 0).
    let r = m * LN_INV_NODE[j] - 1.0;
    let r2 = r * r;
    let tail = r2 * (-0.5 + r * (1.0 / 3.0) + r2 * (-0.25 + r * 0.2 + r2 * (-1.0 / 6.0)));
    (ef * LN2_HI + LN_NODE[j]) + (r + (tail + ef * LN2_LO))
}

/// [`exp`] of every lane, bit for bit: the same operations lane by lane, without branches
/// (the integer steps written with wrapping unsigned arithmetic that keeps the same bits), so
/// that the compiler may pack several lanes into one vector instruction. Lanes outside the
/// fast range are redone by [`exp`].
#[inline(always)]
pub fn exp_lanes<const N: usize>(x: [f64; N]) -> [f64; N] {
    let mut out = [0.0; N];
    let mut all_in_range = true;
    for (o, &x) in out.iter_mut().zip(&x) {
        all_in_range &= x.abs() < 708.0;
        let kd = x * INV_LN2_64 + SHIFT;
        let ki = kd.to_bits();
        let kd = kd - SHIFT;
        let r = (x - kd * LN2_64_HI) - kd * LN2_64_LO;
        let j = (ki & 63) as usize;
        // Bits 6..17 of `k = (ki & (2^52 − 1)) − 2^51` as the exponent field, as in `exp`.
        let k = (ki & ((1 << 52) - 1)).wrapping_sub(1 << 51);
        let scale = f64::from_bits(EXP2_TABLE[j].to_bits().wrapping_add((k >> 6) << 52));
        let r2 = r * r;
        let p = r + r2 * (0.5 + r * (1.0 / 6.0) + r2 * (1.0 / 24.0 + r * (1.0 / 120.0)));
        *o = scale + scale * p;
    }
    if !all_in_range {
        fix_lanes(&x, &mut out, |x| x.abs() < 708.0, exp);
    }
    out
}

/// [`ln`] of every lane, bit for bit, written like [`exp_lanes`]; lanes that are not positive
/// normal numbers are redone by [`ln`].
#[inline(always)]
pub fn ln_lanes<const N: usize>(x: [f64; N]) -> [f64; N] {
    let mut out = [0.0; N];
    let mut all_normal = true;
    for (o, &x) in out.iter_mut().zip(&x) {
        let bits = x.to_bits();
        let biased = bits >> 52;
        all_normal &= biased.wrapping_sub(1) < 0x7FE;
        // `biased − 1023` exactly (both terms are integers below 2^53), without an
        // integer-to-float conversion.
        let ef = f64::from_bits(0x4330_0000_0000_0000 | biased) - (SHIFT_INT + 1023.0);
        *o = ln_of_normal(bits, ef);
    }
    if !all_normal {
        fix_lanes(
            &x,
            &mut out,
            |x| (x.to_bits() >> 52).wrapping_sub(1) < 0x7FE,
            ln,
        );
    }
    out
}

/// `2^52`: a float with this exponent holds an integer below 2^52 in its mantissa bits.
const SHIFT_INT: f64 = 4_503_599_627_370_496.0;

/// Redo with `f` the lanes of `out` whose argument is not `fast`.
#[cold]
#[inline(never)]
fn fix_lanes<const N: usize>(
    x: &[f64; N],
    out: &mut [f64; N],
    fast: impl Fn(f64) -> bool,
    f: fn(f64) -> f64,
) {
    for (o, &x) in out.iter_mut().zip(x) {
        if !fast(x) {
            *o = f(x);
        }
    }
}

/// `v.floor() as i64` without a library call (the baseline x86-64 target has no rounding
/// instruction, so `floor` is a call into `libm`): the same value for every `v`, NaN giving 0
/// and values beyond the range of `i64` saturating.
#[inline(always)]
pub fn floor_i64(v: f64) -> i64 {
    let t = v as i64;
    if (t as f64) > v {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// `v.ceil() as i64` without a library call; see [`floor_i64`].
#[inline(always)]
pub fn ceil_i64(v: f64) -> i64 {
    let t = v as i64;
    if (t as f64) < v {
        t.saturating_add(1)
    } else {
        t
    }
}

/// Nodes of the erf table per unit of the argument.
const ERF_NODES_PER_UNIT: f64 = 32.0;
/// Beyond this argument erf is ±1 to within 2e-17.
const ERF_LIMIT: f64 = 6.0;
/// Taylor coefficients per node (degree 7).
const ERF_TERMS: usize = 8;

/// Nodes of the erf table: `j/32` for `j = 0..=192` (0 to [`ERF_LIMIT`]).
const ERF_TABLE_NODES: usize = 193;

/// Taylor coefficients of erf about each node `j/32`, `j = 0..=192`.
struct ErfTable([[f64; ERF_TERMS]; ERF_TABLE_NODES]);

fn erf_table() -> &'static ErfTable {
    static TABLE: OnceLock<ErfTable> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = [[0.0; ERF_TERMS]; ERF_TABLE_NODES];
        let two_over_sqrt_pi = std::f64::consts::FRAC_2_SQRT_PI;
        for (j, c) in t.iter_mut().enumerate() {
            let x = j as f64 / ERF_NODES_PER_UNIT;
            c[0] = libm::erf(x);
            let g = two_over_sqrt_pi * libm::exp(-x * x);
            // H_0 = 1, H_1 = 2x, H_{n+1} = 2x·H_n − 2n·H_{n−1}.
            let (mut h_prev, mut h) = (0.0, 1.0);
            let mut factorial = 1.0;
            for (n, cn) in c.iter_mut().enumerate().skip(1) {
                factorial *= n as f64;
                let sign = if n % 2 == 1 { 1.0 } else { -1.0 };
                *cn = sign * h * g / factorial;
                let next = 2.0 * x * h - 2.0 * (n - 1) as f64 * h_prev;
                (h_prev, h) = (h, next);
            }
        }
        ErfTable(t)
    })
}

/// A handle on the erf table, for loops that evaluate many values.
#[derive(Clone, Copy)]
pub struct Erf(&'static ErfTable);

impl Erf {
    /// The shared table (built on first use).
    #[inline]
    pub fn new() -> Self {
        Erf(erf_table())
    }

    /// erf(x); absolute error < 5e-16.
    #[inline]
    pub fn eval(&self, x: f64) -> f64 {
        let a = x.abs();
        let v = if a < ERF_LIMIT {
            // `a < 6`, so the index fits an `i32`, whose conversion is cheaper than `usize`'s
            // (the same truncation).
            let j = (a * ERF_NODES_PER_UNIT + 0.5) as i32 as usize;
            let d = a - j as f64 * (1.0 / ERF_NODES_PER_UNIT);
            let c = &self.0 .0[j];
            let d2 = d * d;
            let d4 = d2 * d2;
            (c[0] + d * c[1] + d2 * (c[2] + d * c[3]))
                + d4 * ((c[4] + d * c[5]) + d2 * (c[6] + d * c[7]))
        } else if a >= ERF_LIMIT {
            1.0
        } else {
            return x; // NaN
        };
        if x < 0.0 {
            -v
        } else {
            v
        }
    }
}

impl Erf {
    /// [`Erf::eval`] of every lane, bit for bit: the same operations lane by lane, with
    /// selections instead of branches (lanes outside `[−6, 6]` evaluate the polynomial of
    /// node 0 and discard it), so that the compiler may pack lanes into vector instructions.
    #[inline(always)]
    pub fn eval_lanes<const N: usize>(&self, x: [f64; N]) -> [f64; N] {
        let table = &self.0 .0;
        let mut out = [0.0; N];
        for (o, &x) in out.iter_mut().zip(&x) {
            let a = x.abs();
            let inside = a < ERF_LIMIT;
            let at = if inside { a } else { 0.0 };
            // `at < 6`: the node index is at most 192, the last of the table.
            let j = (at * ERF_NODES_PER_UNIT + 0.5) as i32;
            let d = at - j as f64 * (1.0 / ERF_NODES_PER_UNIT);
            let c = &table[(j as usize).min(table.len() - 1)];
            let d2 = d * d;
            let d4 = d2 * d2;
            let poly = (c[0] + d * c[1] + d2 * (c[2] + d * c[3]))
                + d4 * ((c[4] + d * c[5]) + d2 * (c[6] + d * c[7]));
            // NaN stays NaN, unsigned, as in `eval`.
            let v = if inside {
                poly
            } else if a >= ERF_LIMIT {
                1.0
            } else {
                x
            };
            *o = if x < 0.0 { -v } else { v };
        }
        out
    }
}

impl Erf {
    /// [`Erf::eval_lanes`] of four lanes in AVX2 instructions, bit for bit: each lane's eight
    /// coefficients are gathered from the table, and every other step is one vector
    /// instruction doing the scalar code's IEEE operation in each lane (no fused
    /// multiply-add), with selections where the scalar code branches.
    ///
    /// # Safety
    /// Only where the processor has AVX2 ([`crate::simd::avx2_available`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub unsafe fn eval4_avx2(&self, x: [f64; 4]) -> [f64; 4] {
        use std::arch::x86_64::*;
        let table: *const f64 = self.0 .0.as_ptr().cast();
        let x = _mm256_loadu_pd(x.as_ptr());
        let sign = _mm256_set1_pd(-0.0);
        let limit = _mm256_set1_pd(ERF_LIMIT);
        let a = _mm256_andnot_pd(sign, x);
        let inside = _mm256_cmp_pd::<_CMP_LT_OQ>(a, limit);
        // `inside ? a : 0`, the node index and the offset from the node, as in `eval_lanes`.
        let at = _mm256_and_pd(inside, a);
        let scaled = _mm256_mul_pd(at, _mm256_set1_pd(ERF_NODES_PER_UNIT));
        let j = _mm256_cvttpd_epi32(_mm256_add_pd(scaled, _mm256_set1_pd(0.5)));
        let node = _mm256_mul_pd(
            _mm256_cvtepi32_pd(j),
            _mm256_set1_pd(1.0 / ERF_NODES_PER_UNIT),
        );
        let d = _mm256_sub_pd(at, node);
        let last = ERF_TABLE_NODES as i32 - 1;
        let row = _mm_slli_epi32::<3>(_mm_min_epi32(j, _mm_set1_epi32(last)));
        // SAFETY: `row` is 8·(a node index ≤ the last), `k < 8`: inside the table.
        let c = |k: usize| unsafe { _mm256_i32gather_pd::<8>(table.add(k), row) };
        let (add, mul) = (|u, v| _mm256_add_pd(u, v), |u, v| _mm256_mul_pd(u, v));
        let d2 = mul(d, d);
        let d4 = mul(d2, d2);
        let low = add(add(c(0), mul(d, c(1))), mul(d2, add(c(2), mul(d, c(3)))));
        let high = add(add(c(4), mul(d, c(5))), mul(d2, add(c(6), mul(d, c(7)))));
        let poly = add(low, mul(d4, high));
        // Outside: 1 beyond the limit, `x` itself for NaN; then the sign of `x`.
        let beyond = _mm256_cmp_pd::<_CMP_GE_OQ>(a, limit);
        let outside = _mm256_blendv_pd(x, _mm256_set1_pd(1.0), beyond);
        let v = _mm256_blendv_pd(outside, poly, inside);
        let negative = _mm256_cmp_pd::<_CMP_LT_OQ>(x, _mm256_setzero_pd());
        let mut out = [0.0; 4];
        _mm256_storeu_pd(
            out.as_mut_ptr(),
            _mm256_blendv_pd(v, _mm256_xor_pd(v, sign), negative),
        );
        out
    }
}

impl Default for Erf {
    fn default() -> Self {
        Self::new()
    }
}

/// `2^(j/64)`, correctly rounded.
const EXP2_TABLE: [f64; 64] = [
    1.0,
    1.0108892860517005,
    1.0218971486541166,
    1.0330248790212284,
    1.0442737824274138,
    1.0556451783605572,
    1.0671404006768237,
    1.0787607977571199,
    1.0905077326652577,
    1.102382583307841,
    1.1143867425958924,
    1.1265216186082418,
    1.1387886347566916,
    1.1511892299529827,
    1.1637248587775775,
    1.1763969916502812,
    1.189207115002721,
    1.202156731452703,
    1.215247359980469,
    1.22848053610687,
    1.241857812073484,
    1.255380757024691,
    1.2690509571917332,
    1.2828700160787783,
    1.2968395546510096,
    1.3109612115247644,
    1.3252366431597413,
    1.339667524053303,
    1.3542555469368927,
    1.3690024229745905,
    1.383909881963832,
    1.3989796725383112,
    std::f64::consts::SQRT_2,
    1.42961333839197,
    1.4451808069770467,
    1.460917794180647,
    1.4768261459394993,
    1.4929077282912648,
    1.5091644275934228,
    1.5255981507445384,
    1.5422108254079407,
    1.559004400237837,
    1.5759808451078865,
    1.593142151342267,
    1.6104903319492543,
    1.6280274218573478,
    1.645755478153965,
    1.6636765803267364,
    1.681792830507429,
    1.7001063537185235,
    1.718619298122478,
    1.7373338352737062,
    1.7562521603732995,
    1.7753764925265212,
    1.7947090750031072,
    1.8142521755003989,
    1.8340080864093424,
    1.8539791250833855,
    1.8741676341103,
    1.8945759815869656,
    1.9152065613971474,
    1.9360617934922943,
    1.9571441241754002,
    1.978456026387951,
];

/// `1/c_j` rounded, `c_j = 1 + j/128` the nodes of `[1, 2]`.
const LN_INV_NODE: [f64; 129] = [
    1.0,
    0.9922480620155039,
    0.9846153846153847,
    0.9770992366412213,
    0.9696969696969697,
    0.9624060150375939,
    0.9552238805970149,
    0.9481481481481482,
    0.9411764705882353,
    0.9343065693430657,
    0.927536231884058,
    0.920863309352518,
    0.9142857142857143,
    0.9078014184397163,
    0.9014084507042254,
    0.8951048951048951,
    0.8888888888888888,
    0.8827586206896552,
    0.8767123287671232,
    0.8707482993197279,
    0.8648648648648649,
    0.8590604026845637,
    0.8533333333333334,
    0.847682119205298,
    0.8421052631578947,
    0.8366013071895425,
    0.8311688311688312,
    0.8258064516129032,
    0.8205128205128205,
    0.8152866242038217,
    0.810126582278481,
    0.8050314465408805,
    0.8,
    0.7950310559006211,
    0.7901234567901234,
    0.7852760736196319,
    0.7804878048780488,
    0.7757575757575758,
    0.7710843373493976,
    0.7664670658682635,
    0.7619047619047619,
    0.757396449704142,
    0.7529411764705882,
    0.7485380116959064,
    0.7441860465116279,
    0.7398843930635838,
    0.735632183908046,
    0.7314285714285714,
    0.7272727272727273,
    0.7231638418079096,
    0.7191011235955056,
    0.7150837988826816,
    0.7111111111111111,
    0.7071823204419889,
    0.7032967032967034,
    0.6994535519125683,
    0.6956521739130435,
    0.6918918918918919,
    0.6881720430107527,
    0.6844919786096256,
    0.6808510638297872,
    0.6772486772486772,
    0.6736842105263158,
    0.6701570680628273,
    0.6666666666666666,
    0.6632124352331606,
    0.6597938144329897,
    0.6564102564102564,
    0.6530612244897959,
    0.649746192893401,
    0.6464646464646465,
    0.6432160804020101,
    0.64,
    0.6368159203980099,
    0.6336633663366337,
    0.6305418719211823,
    0.6274509803921569,
    0.624390243902439,
    0.6213592233009708,
    0.6183574879227053,
    0.6153846153846154,
    0.6124401913875598,
    0.6095238095238096,
    0.6066350710900474,
    0.6037735849056604,
    0.6009389671361502,
    0.5981308411214953,
    0.5953488372093023,
    0.5925925925925926,
    0.5898617511520737,
    0.5871559633027523,
    0.5844748858447488,
    0.5818181818181818,
    0.579185520361991,
    0.5765765765765766,
    0.5739910313901345,
    0.5714285714285714,
    0.5688888888888889,
    0.5663716814159292,
    0.5638766519823789,
    0.5614035087719298,
    0.5589519650655022,
    0.5565217391304348,
    0.5541125541125541,
    0.5517241379310345,
    0.5493562231759657,
    0.5470085470085471,
    0.5446808510638298,
    0.5423728813559322,
    0.540084388185654,
    0.5378151260504201,
    0.5355648535564853,
    0.5333333333333333,
    0.5311203319502075,
    0.5289256198347108,
    0.5267489711934157,
    0.5245901639344263,
    0.5224489795918368,
    0.5203252032520326,
    0.5182186234817814,
    0.5161290322580645,
    0.5140562248995983,
    0.512,
    0.5099601593625498,
    0.5079365079365079,
    0.5059288537549407,
    0.5039370078740157,
    0.5019607843137255,
    0.5,
];

/// `−ln(LN_INV_NODE[j])` of the rounded inverse, correctly rounded.
const LN_NODE: [f64; 129] = [
    0.0,
    0.007782140442054963,
    0.015504186535965199,
    0.023167059281534418,
    0.03077165866675366,
    0.03831886430213666,
    0.04580953603129422,
    0.05324451451881224,
    0.060624621816434854,
    0.06795066190850778,
    0.07522342123758752,
    0.08244366921107454,
    0.08961215868968717,
    0.09672962645855114,
    0.10379679368164355,
    0.11081436634029011,
    0.11778303565638351,
    0.12470347850095725,
    0.13157635778871932,
    0.1384023228591192,
    0.14518200984449783,
    0.151916042025842,
    0.15860503017663852,
    0.16524957289530717,
    0.17185025692665928,
    0.17840765747281825,
    0.18492233849401193,
    0.19139485299962947,
    0.19782574332991992,
    0.20421554142869083,
    0.21056476910734964,
    0.2168739383006143,
    0.2231435513142097,
    0.2293741010648459,
    0.23556607131276697,
    0.24171993688714513,
    0.2478361639045812,
    0.25391520998096345,
    0.259957524436926,
    0.2659635484971379,
    0.2719337154836418,
    0.2778684510034563,
    0.2837681731306446,
    0.2896332925830427,
    0.2954642128938359,
    0.30126133057816185,
    0.3070250352949119,
    0.3127557100038969,
    0.3184537311185346,
    0.324119468654212,
    0.32975328637246804,
    0.3353555419211378,
    0.3409265869705932,
    0.3464667673462086,
    0.3519764231571781,
    0.3574558889218038,
    0.3629054936893685,
    0.36832556115870757,
    0.373716409793584,
    0.3790783529349695,
    0.38441169891033206,
    0.38971675114002524,
    0.394993808240869,
    0.40024316412701266,
    0.40546510810816444,
    0.4106599249852683,
    0.415827895143711,
    0.42096929464412963,
    0.42608439531090014,
    0.43117346481837143,
    0.43623676677491796,
    0.4412745608048752,
    0.4462871026284195,
    0.4512746441394586,
    0.4562374334815876,
    0.46117571512217015,
    0.46608972992459924,
    0.470979715218791,
    0.475845904869964,
    0.48068852934575196,
    0.48550781578170077,
    0.4903039880451939,
    0.4950772667978514,
    0.49982786955644926,
    0.5045560107523953,
    0.5092619017898079,
    0.5139457511022344,
    0.5186077642080457,
    0.5232481437645479,
    0.5278670896208424,
    0.5324647988694717,
    0.5370414658968837,
    0.5415972824327444,
    0.5461324375981356,
    0.5506471179526623,
    0.5551415075405016,
    0.5596157879354228,
    0.564070138284803,
    0.5685047353526688,
    0.5729197535617854,
    0.5773153650348236,
    0.5816917396346225,
    0.5860490450035782,
    0.5903874466021763,
    0.5947071077466928,
    0.5990081896460834,
    0.6032908514380841,
    0.6075552502245418,
    0.6118015411059929,
    0.616029877215514,
    0.6202404097518576,
    0.6244332880118936,
    0.6286086594223742,
    0.6327666695710378,
    0.6369074622370692,
    0.6410311794209312,
    0.6451379613735847,
    0.6492279466251097,
    0.6533012720127456,
    0.65735807270836,
    0.661398482245365,
    0.6654226325450905,
    0.6694306539426292,
    0.6734226752121667,
    0.6773988235918061,
    0.6813592248079031,
    0.6853040030989195,
    0.689233281238809,
    std::f64::consts::LN_2,
];

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic spread of test arguments in `[lo, hi]`.
    fn points(lo: f64, hi: f64, n: usize) -> impl Iterator<Item = f64> {
        let mut state = 0x1234_5678_9ABC_DEF0u64;
        (0..n).map(move |_| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            lo + (hi - lo) * ((state >> 11) as f64 / (1u64 << 53) as f64)
        })
    }

    #[test]
    fn lane_functions_give_the_scalar_bits() {
        let mut values: Vec<f64> = points(-750.0, 750.0, 4000)
            .chain(points(-1.0, 1.0, 4000))
            .chain(points(0.0, 1e-300, 100))
            .collect();
        values.extend([
            0.0,
            -0.0,
            1.0,
            -1.0,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            707.9,
            708.0,
            709.5,
            -708.0,
            -745.0,
        ]);
        values.resize(values.len().next_multiple_of(8), 2.0);
        let erf = Erf::new();
        for chunk in values.chunks_exact(8) {
            let x: [f64; 8] = chunk.try_into().unwrap();
            let (e, l) = (exp_lanes(x), ln_lanes(x));
            let small = x.map(|v| v / 100.0);
            let f = erf.eval_lanes(small);
            for k in 0..8 {
                assert_eq!(
                    f[k].to_bits(),
                    erf.eval(small[k]).to_bits(),
                    "erf({})",
                    small[k]
                );
                assert_eq!(e[k].to_bits(), exp(x[k]).to_bits(), "exp({})", x[k]);
                assert_eq!(l[k].to_bits(), ln(x[k]).to_bits(), "ln({})", x[k]);
            }
        }
    }

    #[test]
    fn floor_and_ceil_match_the_library() {
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.5,
            -2.5,
            1e-300,
            -1e-300,
            4503599627370495.5,
            -4503599627370495.5,
            9.3e18,
            -9.3e18,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            i64::MAX as f64,
            i64::MIN as f64,
        ];
        values.extend(points(-70.0, 70.0, 10_001));
        for v in values {
            assert_eq!(floor_i64(v), v.floor() as i64, "floor {v}");
            assert_eq!(ceil_i64(v), v.ceil() as i64, "ceil {v}");
        }
    }

    #[test]
    fn exp_is_within_4p5e_16_of_libm() {
        for x in points(-700.0, 700.0, 200_000).chain(points(-1.0, 1.0, 200_000)) {
            let (a, b) = (exp(x), libm::exp(x));
            assert!((a - b).abs() <= 4.5e-16 * b, "exp({x}) = {a}, libm {b}");
        }
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-800.0), 0.0);
        assert_eq!(exp(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp(800.0), f64::INFINITY);
        assert!((exp(709.5) / libm::exp(709.5) - 1.0).abs() < 9e-16);
        assert!(exp(f64::NAN).is_nan());
    }

    #[test]
    fn ln_is_within_its_bound_of_libm() {
        for x in points(1e-3, 4.0, 200_000)
            .chain(points(0.5, 2.0, 200_000))
            .chain(points(1.0, 1e30, 100_000))
        {
            let (a, b) = (ln(x), libm::log(x));
            assert!(
                (a - b).abs() <= 3e-16 + 2.3e-16 * b.abs(),
                "ln({x}) = {a}, libm {b}"
            );
        }
        assert_eq!(ln(1.0), 0.0);
        assert_eq!(ln(0.0), f64::NEG_INFINITY);
        assert!(ln(-1.0).is_nan());
        assert_eq!(ln(1e-310), 1e-310f64.ln());
    }

    #[test]
    fn erf_lanes_and_avx2_lanes_are_the_scalar_erf_bit_for_bit() {
        let erf = Erf::new();
        let special = [
            0.0,
            -0.0,
            1e-310,
            -1e-310,
            ERF_LIMIT,
            -ERF_LIMIT,
            ERF_LIMIT - 1e-15,
            1.0 / 64.0,
            192.5 / 32.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MAX,
        ];
        let mut xs: Vec<f64> = special.to_vec();
        xs.extend(points(-7.0, 7.0, 200_000));
        // Whole groups of four lanes: none of the arguments is left out.
        xs.resize(xs.len().div_ceil(4) * 4, 0.5);
        for lanes in xs.chunks_exact(4) {
            let x: [f64; 4] = lanes.try_into().unwrap();
            let want = x.map(|x| erf.eval(x).to_bits());
            assert_eq!(erf.eval_lanes(x).map(f64::to_bits), want, "{x:?}");
            #[cfg(target_arch = "x86_64")]
            if crate::simd::avx2_available() {
                // SAFETY: the processor has AVX2.
                let got = unsafe { erf.eval4_avx2(x) };
                assert_eq!(got.map(f64::to_bits), want, "{x:?}");
            }
        }
    }

    #[test]
    fn erf_is_within_5e_16_of_libm() {
        let erf = |x| Erf::new().eval(x);
        for x in points(-7.0, 7.0, 400_000) {
            let (a, b) = (erf(x), libm::erf(x));
            assert!((a - b).abs() <= 5e-16, "erf({x}) = {a}, libm {b}");
        }
        assert_eq!(erf(0.0), 0.0);
        assert_eq!(erf(f64::INFINITY), 1.0);
        assert_eq!(erf(-9.0), -1.0);
        assert!(erf(f64::NAN).is_nan());
    }
}
