//! Deterministic random numbers for the simulator, independent of any crate's version.
//!
//! xoshiro256++ (Blackman & Vigna, "Scrambled linear pseudorandom number generators",
//! ACM TOMS 2021) seeded through SplitMix64 (Steele, Lea & Flood, OOPSLA 2014). Separate
//! streams (seeding, sensor fixed pattern, temporal noise, per pixel or per particle) are
//! derived from the user's seed and a stream label, so results do not depend on the order in
//! which threads draw numbers.

/// A stream label: which part of the simulation draws from a generator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub enum Stream {
    /// Particle positions, sizes and brightness.
    Seeding = 1,
    /// Fixed-pattern properties of one sensor instance (threshold mismatch, hot pixels).
    FixedPattern = 2,
    /// Temporal noise (jitter, leak and shot noise).
    Temporal = 3,
    /// Re-seeding of particles that left the field of view.
    Reseeding = 4,
    /// Random flows ([`crate::sim::flow::RandomVortices`]): vortex positions and signs.
    Flow = 5,
}

/// xoshiro256++ generator.
#[derive(Debug, Clone)]
pub struct Rng {
    s: [u64; 4],
    spare_normal: Option<f64>,
}

/// The SplitMix64 state from which the generator of `stream` and item `index` of `seed`
/// draws its four words.
#[inline]
fn splitmix_start(seed: u64, stream: Stream, index: u64) -> u64 {
    seed ^ (stream as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93)
        ^ index.wrapping_mul(0xA076_1D64_78BD_642F)
}

/// The increment of the SplitMix64 state per output.
const SPLITMIX_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(SPLITMIX_GAMMA);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    /// The generator for `stream` and item `index` (a pixel, a particle, a band) of `seed`.
    pub fn new(seed: u64, stream: Stream, index: u64) -> Self {
        let mut state = splitmix_start(seed, stream, index);
        let s = [
            splitmix64(&mut state),
            splitmix64(&mut state),
            splitmix64(&mut state),
            splitmix64(&mut state),
        ];
        Rng {
            s,
            spare_normal: None,
        }
    }

    /// `Rng::new(seed, stream, index).normal_fast()`, bit for bit, for one draw per
    /// generator (the jitter of one event): the first 64 bits of xoshiro256++ read only the
    /// first and last words of the state, so only those two are mixed from the seed; the
    /// whole generator is made only when the draw falls outside the ziggurat's inner
    /// rectangles (about 1 % of draws).
    #[inline]
    pub fn first_normal(seed: u64, stream: Stream, index: u64) -> f64 {
        let mut state = splitmix_start(seed, stream, index);
        let s0 = splitmix64(&mut state);
        // Words 1 and 2 each advance the splitmix state by its increment.
        state = state.wrapping_add(SPLITMIX_GAMMA.wrapping_mul(2));
        let s3 = splitmix64(&mut state);
        let bits = s0.wrapping_add(s3).rotate_left(23).wrapping_add(s0);
        let (layer, u) = ziggurat_layer(bits);
        let z = ziggurat();
        if u.abs() < z.ratio[layer] {
            return u * z.x[layer];
        }
        Rng::new(seed, stream, index).normal_fast()
    }

    /// Next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.s;
        let result = s[0].wrapping_add(s[3]).rotate_left(23).wrapping_add(s[0]);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    #[inline]
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Standard normal (Box–Muller, both values used).
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare_normal.take() {
            return z;
        }
        let u1 = 1.0 - self.uniform(); // (0, 1]
        let u2 = self.uniform();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        self.spare_normal = Some(r * s);
        r * c
    }

    /// Standard normal by the ziggurat method (Marsaglia & Tsang, J. Stat. Softw. 5(8), 2000,
    /// in Doornik's form, "An improved ziggurat method to generate normal random samples",
    /// 2005): 128 layers of equal area under the density, one 64-bit draw for most values
    /// (low 7 bits pick the layer, the top 53 the abscissa), an exponential only in the
    /// wedges (about 1 % of draws) and the tail beyond 3.44. Exactly normal; the tables and
    /// the rare exponentials use deterministic functions, so results are the same on every
    /// machine. For the simulator's many per-pixel and per-event draws.
    #[inline(always)]
    pub fn normal_fast(&mut self) -> f64 {
        let z = ziggurat();
        let (layer, u) = self.ziggurat_draw();
        if u.abs() < z.ratio[layer] {
            return u * z.x[layer];
        }
        self.normal_rare(layer, u)
    }

    /// A layer of the ziggurat (low 7 bits) and a uniform abscissa in (−1, 1) (top 53 bits)
    /// from one 64-bit draw.
    #[inline(always)]
    fn ziggurat_draw(&mut self) -> (usize, f64) {
        ziggurat_layer(self.next_u64())
    }

    /// The rest of [`Rng::normal_fast`] after a draw `(layer, u)` outside the layer's inner
    /// rectangle: the tail, or the wedge test, then new draws until one is accepted.
    #[cold]
    #[inline(never)]
    fn normal_rare(&mut self, mut layer: usize, mut u: f64) -> f64 {
        let z = ziggurat();
        loop {
            if u.abs() < z.ratio[layer] {
                return u * z.x[layer];
            }
            if layer == 0 {
                return self.normal_tail(u < 0.0);
            }
            let x = u * z.x[layer];
            let (x0, x1) = (z.x[layer], z.x[layer + 1]);
            let f0 = super::fastmath::exp(-0.5 * (x0 * x0 - x * x));
            let f1 = super::fastmath::exp(-0.5 * (x1 * x1 - x * x));
            if f1 + self.uniform() * (f0 - f1) < 1.0 {
                return x;
            }
            (layer, u) = self.ziggurat_draw();
        }
    }

    /// A normal beyond the ziggurat's base `R` (Marsaglia's tail method), negative if asked.
    #[cold]
    fn normal_tail(&mut self, negative: bool) -> f64 {
        loop {
            let a = super::fastmath::ln(1.0 - self.uniform()) / ZIGGURAT_R;
            let b = super::fastmath::ln(1.0 - self.uniform());
            if -2.0 * b >= a * a {
                return if negative {
                    a - ZIGGURAT_R
                } else {
                    ZIGGURAT_R - a
                };
            }
        }
    }

    /// Exponentially distributed waiting time with the given rate (per unit of the result).
    pub fn exponential(&mut self, rate: f64) -> f64 {
        -(1.0 - self.uniform()).ln() / rate
    }
}

/// A layer of the ziggurat (low 7 bits of `bits`) and a uniform abscissa in (−1, 1) (top 53
/// bits).
#[inline(always)]
fn ziggurat_layer(bits: u64) -> (usize, f64) {
    let layer = (bits & (ZIGGURAT_LAYERS as u64 - 1)) as usize;
    let u = 2.0 * ((bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)) - 1.0;
    (layer, u)
}

/// Layers of the ziggurat of [`Rng::normal_fast`].
const ZIGGURAT_LAYERS: usize = 128;
/// Where the base layer's tail starts, and the common area of the layers, for 128 layers
/// (Marsaglia & Tsang 2000).
const ZIGGURAT_R: f64 = 3.442_619_855_899;
const ZIGGURAT_V: f64 = 9.912_563_035_262_17e-3;

/// Layer edges `x[i]` (`x[0]` the base layer's width `V/f(R)`, `x[1] = R`, down to
/// `x[128] = 0`) and `ratio[i] = x[i+1]/x[i]`, the part of layer `i` that lies wholly under
/// the density `f(x) = exp(−x²/2)`.
struct Ziggurat {
    x: [f64; ZIGGURAT_LAYERS + 1],
    ratio: [f64; ZIGGURAT_LAYERS],
}

fn ziggurat() -> &'static Ziggurat {
    static TABLE: std::sync::OnceLock<Ziggurat> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let mut x = [0.0; ZIGGURAT_LAYERS + 1];
        let mut f = libm::exp(-0.5 * ZIGGURAT_R * ZIGGURAT_R);
        x[0] = ZIGGURAT_V / f;
        x[1] = ZIGGURAT_R;
        for i in 2..ZIGGURAT_LAYERS {
            // Layer i − 1 spans [f(x[i−1]), f(x[i])] with area V = x[i−1]·(f(x[i]) − f(x[i−1])).
            x[i] = (-2.0 * libm::log(ZIGGURAT_V / x[i - 1] + f)).sqrt();
            f = libm::exp(-0.5 * x[i] * x[i]);
        }
        let mut ratio = [0.0; ZIGGURAT_LAYERS];
        for i in 0..ZIGGURAT_LAYERS {
            ratio[i] = x[i + 1] / x[i];
        }
        Ziggurat { x, ratio }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The one-draw shortcut gives the generator's first normal, bit for bit, on the fast
    /// path and on the rare one (both occur among 200 000 indices).
    #[test]
    fn first_normal_is_the_generators_first_normal() {
        let mut rare = 0;
        for index in 0..200_000u64 {
            let seed = index.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 77;
            let want = Rng::new(seed, Stream::Temporal, index << 7).normal_fast();
            let got = Rng::first_normal(seed, Stream::Temporal, index << 7);
            assert_eq!(got.to_bits(), want.to_bits(), "index {index}");
            let mut rng = Rng::new(seed, Stream::Temporal, index << 7);
            let (layer, u) = rng.ziggurat_draw();
            rare += usize::from(u.abs() >= ziggurat().ratio[layer]);
        }
        assert!(rare > 100, "{rare}");
    }

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let mut a = Rng::new(7, Stream::Seeding, 0);
        let mut b = Rng::new(7, Stream::Seeding, 0);
        let mut c = Rng::new(7, Stream::Temporal, 0);
        let mut d = Rng::new(7, Stream::Seeding, 1);
        let xa: Vec<u64> = (0..4).map(|_| a.next_u64()).collect();
        let xb: Vec<u64> = (0..4).map(|_| b.next_u64()).collect();
        assert_eq!(xa, xb);
        assert_ne!(xa[0], c.next_u64());
        assert_ne!(xa[0], d.next_u64());
    }

    #[test]
    fn moments_of_uniform_normal_exponential() {
        let mut r = Rng::new(1, Stream::Temporal, 0);
        let n = 200_000;
        let u: f64 = (0..n).map(|_| r.uniform()).sum::<f64>() / n as f64;
        assert!((u - 0.5).abs() < 0.005, "{u}");
        let z: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let mean = z.iter().sum::<f64>() / n as f64;
        let var = z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.01 && (var - 1.0).abs() < 0.02,
            "{mean} {var}"
        );
        let e = (0..n).map(|_| r.exponential(4.0)).sum::<f64>() / n as f64;
        assert!((e - 0.25).abs() < 0.005, "{e}");
    }

    #[test]
    fn ziggurat_normal_has_the_normal_distribution() {
        let mut r = Rng::new(3, Stream::Temporal, 9);
        let n = 2_000_000;
        let z: Vec<f64> = (0..n).map(|_| r.normal_fast()).collect();
        let mean = z.iter().sum::<f64>() / n as f64;
        let var = z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
        let kurtosis = z.iter().map(|v| (v - mean).powi(4)).sum::<f64>() / n as f64 / var / var;
        assert!(
            mean.abs() < 0.005 && (var - 1.0).abs() < 0.005,
            "{mean} {var}"
        );
        assert!((kurtosis - 3.0).abs() < 0.03, "{kurtosis}");
        // Φ at points inside the layers, on the wedges and in the tail; binomial σ ≤ 3.6e-4.
        for (q, phi) in [
            (-3.7, 1.077_997_1e-4),
            (-2.0, 0.022_750_13),
            (-1.0, 0.158_655_25),
            (-0.3, 0.382_088_58),
            (0.0, 0.5),
            (0.7, 0.758_036_35),
            (1.5, 0.933_192_80),
            (3.0, 0.998_650_10),
        ] {
            let p = z.iter().filter(|&&v| v < q).count() as f64 / n as f64;
            let sigma = (phi * (1.0 - phi) / n as f64).sqrt();
            assert!(
                (p - phi).abs() < 5.0 * sigma + 1e-6,
                "P(z < {q}) = {p}, Φ = {phi}"
            );
        }
    }
}
