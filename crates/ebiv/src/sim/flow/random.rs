//! A turbulence-like test flow: a steady sum of randomly placed Lamb–Oseen vortices of both
//! senses over a uniform stream.
//!
//! Fields of random vortices are the usual stand-in for turbulence in tests of velocimetry
//! algorithms: they have a broad, continuous distribution of velocities in both components
//! and of velocity gradients, which is what exposes peak locking in velocity histograms
//! (Christensen 2004, Exp. Fluids 36:484; the EBIV paper's star-shaped histograms, Willert &
//! Klinner 2022, Exp. Fluids 63:101). Each vortex has the same core radius and the same peak
//! tangential speed; its position is uniform over the region and its sense of rotation
//! random, both drawn from the flow's own seed ([`Stream::Flow`]), so the flow is the same
//! for every particle seed of a study.

use super::{Flow, LambOseenVortex, LAMB_OSEEN_PEAK_Q};
use crate::sim::rng::{Rng, Stream};

/// Steady sum of `vortices` and a uniform `mean` stream.
#[derive(Debug, Clone, PartialEq)]
pub struct RandomVortices {
    /// The vortices.
    pub vortices: Vec<LambOseenVortex>,
    /// The uniform stream (u, v) they are carried in, px/ms.
    pub mean: (f64, f64),
}

impl RandomVortices {
    /// `count` vortices of core radius `core_radius` px and peak tangential speed `speed`
    /// px/ms, centred uniformly over `[0, width] × [0, height]` px with random senses drawn
    /// from `seed`, in the uniform stream `mean` px/ms.
    pub fn new(
        count: u32,
        core_radius: f64,
        speed: f64,
        (width, height): (f64, f64),
        mean: (f64, f64),
        seed: u64,
    ) -> RandomVortices {
        // u_θ peaks at r² = q r_c² with u_max = Γ (1 − e^{−q}) / (2π r_c √q).
        let q = LAMB_OSEEN_PEAK_Q;
        let circulation =
            speed * 2.0 * std::f64::consts::PI * core_radius * q.sqrt() / (1.0 - (-q).exp());
        let mut rng = Rng::new(seed, Stream::Flow, 0);
        let vortices = (0..count)
            .map(|_| {
                let centre = (rng.range(0.0, width), rng.range(0.0, height));
                let sense = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                LambOseenVortex {
                    centre,
                    circulation_px2_per_ms: sense * circulation,
                    core_radius_px: core_radius,
                }
            })
            .collect();
        RandomVortices { vortices, mean }
    }
}

impl Flow for RandomVortices {
    fn velocity(&self, x: f64, y: f64, t_us: f64) -> (f64, f64) {
        self.vortices.iter().fold(self.mean, |(u, v), vortex| {
            let (du, dv) = vortex.velocity(x, y, t_us);
            (u + du, v + dv)
        })
    }

    fn max_speed(&self, w: f64, h: f64, t_us: f64) -> f64 {
        self.mean.0.hypot(self.mean.1)
            + self
                .vortices
                .iter()
                .map(|v| v.max_speed(w, h, t_us))
                .sum::<f64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_vortex_peaks_at_the_given_speed_and_the_seed_fixes_the_field() {
        let f = RandomVortices::new(6, 20.0, 1.5, (200.0, 100.0), (0.5, 0.0), 3);
        assert_eq!(f.vortices.len(), 6);
        for v in &f.vortices {
            let peak = v.tangential_velocity(v.peak_radius()).abs();
            assert!((peak - 1.5).abs() < 1e-9, "{peak}");
            assert!((0.0..=200.0).contains(&v.centre.0) && (0.0..=100.0).contains(&v.centre.1));
        }
        assert!(f.vortices.iter().any(|v| v.circulation_px2_per_ms < 0.0));
        assert!(f.vortices.iter().any(|v| v.circulation_px2_per_ms > 0.0));
        assert_eq!(
            f,
            RandomVortices::new(6, 20.0, 1.5, (200.0, 100.0), (0.5, 0.0), 3)
        );
        assert_ne!(
            f,
            RandomVortices::new(6, 20.0, 1.5, (200.0, 100.0), (0.5, 0.0), 4)
        );
        let far = f.velocity(1e6, 1e6, 0.0);
        assert!((far.0 - 0.5).abs() < 1e-3 && far.1.abs() < 1e-3, "{far:?}");
    }
}
